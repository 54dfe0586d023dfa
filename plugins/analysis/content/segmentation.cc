#include "segmentation.h"

#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "image_content.h"

namespace locforge::analysis {

cv::Mat PersonMask(const cv::Mat& probability, cv::Size image_size, double threshold) {
  if (probability.empty() || probability.type() != CV_32F)
    throw std::invalid_argument("PersonMask: needs a one-channel float probability map");
  cv::Mat resized;
  cv::resize(probability, resized, image_size, 0, 0, cv::INTER_LINEAR);
  cv::Mat mask = resized >= threshold;  // 255 / 0
  return mask;
}

MaskAgreement CompareMasks(const cv::Mat& estimate, const cv::Mat& reference) {
  if (estimate.size() != reference.size() || estimate.type() != CV_8U || reference.type() != CV_8U)
    throw std::invalid_argument("CompareMasks: needs two 8-bit masks of one size");
  const cv::Mat e = estimate > 127, r = reference > 127;
  const double both = cv::countNonZero(e & r), any = cv::countNonZero(e | r);
  MaskAgreement a;
  a.iou = any > 0 ? both / any : 1.0;
  a.estimated_percent = CrowdednessPercent(estimate);
  a.reference_percent = CrowdednessPercent(reference);
  return a;
}

}  // namespace locforge::analysis

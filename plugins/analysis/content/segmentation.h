// Person masks from a segmentation network's output, and their agreement
// with reference masks (the simulator's truth): what analysis/person_segmentation
// computes per image.
#ifndef LOCFORGE_PLUGINS_ANALYSIS_CONTENT_SEGMENTATION_H_
#define LOCFORGE_PLUGINS_ANALYSIS_CONTENT_SEGMENTATION_H_

#include <opencv2/core.hpp>

namespace locforge::analysis {

// A person probability map (h x w, CV_32F in [0, 1]) resized bilinearly to
// `image_size` and thresholded: CV_8U, 255 where p >= threshold.
cv::Mat PersonMask(const cv::Mat& probability, cv::Size image_size, double threshold);

struct MaskAgreement {
  double iou = 1;                    // |E & R| / |E | R| (1 when both are empty)
  double estimated_percent = 0;      // crowdedness of the estimate (% pixels)
  double reference_percent = 0;      // crowdedness of the reference
};

// Both masks CV_8U of one size, > 127 = person.
MaskAgreement CompareMasks(const cv::Mat& estimate, const cv::Mat& reference);

}  // namespace locforge::analysis

#endif  // LOCFORGE_PLUGINS_ANALYSIS_CONTENT_SEGMENTATION_H_

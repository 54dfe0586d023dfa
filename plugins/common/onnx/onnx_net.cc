#include "onnx_net.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <map>
#include <vector>

#include "locforge/error.h"
#include "locforge/kapture/kapture.h"

namespace locforge::learned {

cv::dnn::Net& ThreadNet(const std::string& model) {
  thread_local std::map<std::string, cv::dnn::Net> nets;
  auto it = nets.find(model);
  if (it != nets.end()) return it->second;
  cv::dnn::Net net;
  try {
    net = cv::dnn::readNetFromONNX(model);
  } catch (const cv::Exception& e) {
    throw InputError(model, 0, "model", std::string("cannot load the ONNX model: ") + e.what());
  }
  if (net.empty()) throw InputError(model, 0, "model", "cannot load the ONNX model");
  return nets.emplace(model, std::move(net)).first->second;
}

cv::Mat ToBlob(const cv::Mat& image) {
  const int sizes[4] = {1, 3, image.rows, image.cols};
  cv::Mat blob(4, sizes, CV_32F);
  std::vector<cv::Mat> planes;
  for (int c = 0; c < 3; ++c)
    planes.emplace_back(image.rows, image.cols, CV_32F, blob.ptr<float>(0, c));
  cv::split(image, planes);
  return blob;
}

double SecondsSince(const std::chrono::steady_clock::time_point& start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

cv::Mat ReadRgb(const std::filesystem::path& dataset, const std::string& image) {
  const fs::path file = kapture::Kapture(dataset).ExistingRecordDataPath(image, kapture::layout::RecordsFile("camera"));
  const cv::Mat bgr = cv::imread(file.string(), cv::IMREAD_COLOR);
  if (bgr.empty())
    throw InputError(kapture::layout::RecordsFile("camera"), 0, "image_path",
                     "cannot read image '" + image + "' at " + file.string());
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

}  // namespace locforge::learned

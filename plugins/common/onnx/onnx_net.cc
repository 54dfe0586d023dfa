#include "onnx_net.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <map>
#include <vector>

#include "image_read.h"
#include "locforge/error.h"
#include "locforge/kapture/kapture.h"

namespace locforge::learned {

cv::dnn::Net& ThreadNet(const std::string& model) {
  // Keyed by the file's size and modification time too: a model rewritten
  // at the same path (retrained between two runs of one process) is
  // reloaded, never served stale.
  struct Entry {
    std::string stamp;
    cv::dnn::Net net;
  };
  thread_local std::map<std::string, Entry> nets;
  std::error_code ec;
  const auto size = fs::file_size(model, ec);
  const auto time = fs::last_write_time(model, ec);
  const std::string stamp = ec ? "" : std::to_string(size) + "@" + std::to_string(time.time_since_epoch().count());
  auto it = nets.find(model);
  if (it != nets.end() && it->second.stamp == stamp) return it->second.net;
  cv::dnn::Net net;
  try {
    net = cv::dnn::readNetFromONNX(model);
  } catch (const cv::Exception& e) {
    throw InputError(model, 0, "model", std::string("cannot load the ONNX model: ") + e.what());
  }
  if (net.empty()) throw InputError(model, 0, "model", "cannot load the ONNX model");
  Entry& entry = nets[model];
  entry = Entry{stamp, std::move(net)};
  return entry.net;
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
  const cv::Mat bgr = image_io::ReadCameraImage(dataset, image, cv::IMREAD_COLOR);
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

}  // namespace locforge::learned

#include "image_input.h"

#include <opencv2/imgproc.hpp>

namespace locforge::learned {

bool InputOptions::Check(std::string* why) const {
  if (input.empty()) return *why = "input: empty tensor name", false;
  if (mean.size() != 3) return *why = "mean: 3 values (R, G, B) expected", false;
  if (std.size() != 3) return *why = "std: 3 values (R, G, B) expected", false;
  for (double s : std)
    if (!(s > 0)) return *why = "std: every value must be > 0", false;
  return true;
}

cv::Mat InputBlob(const cv::Mat& rgb, const InputOptions& o) {
  cv::Mat resized;
  cv::resize(rgb, resized, cv::Size(o.width, o.height), 0, 0, cv::INTER_AREA);
  const int sizes[4] = {1, 3, o.height, o.width};
  cv::Mat blob(4, sizes, CV_32F);
  for (int c = 0; c < 3; ++c) {
    float* plane = blob.ptr<float>(0, c);
    for (int y = 0; y < o.height; ++y)
      for (int x = 0; x < o.width; ++x)
        plane[y * o.width + x] =
            static_cast<float>((resized.at<cv::Vec3b>(y, x)[c] - o.mean[c]) / o.std[c]);
  }
  return blob;
}

}  // namespace locforge::learned

// The input convention of the fixed-size networks (localizer/posenet,
// localizer/esac, analysis/person_segmentation): parameters and blob.
#ifndef LOCFORGE_PLUGINS_COMMON_ONNX_IMAGE_INPUT_H_
#define LOCFORGE_PLUGINS_COMMON_ONNX_IMAGE_INPUT_H_

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "locforge/params.h"

namespace locforge::learned {

// The image resized to width x height (aspect not kept, area filter),
// channels RGB, value = (pixel - mean) / std with pixel in [0, 255].
struct InputOptions {
  std::string input = "image";  // Input tensor name (1x3xHxW float32).
  int width = 224;              // Network input width.
  int height = 224;             // Network input height.
  std::vector<double> mean = {123.675, 116.28, 103.53};  // Per channel (RGB), ImageNet.
  std::vector<double> std = {58.395, 57.12, 57.375};     // Per channel (RGB), ImageNet.
  bool Check(std::string* why) const;
};

template <typename Options>
void DeclareInputOptions(ParamSchema<Options>& s) {
  s.template Add<std::string>("input", &InputOptions::input, "input tensor name (1x3xHxW float32)");
  s.template Add<int>("width", &InputOptions::width,
                      "network input width (the image is resized, aspect not kept)").Range(8, 4096);
  s.template Add<int>("height", &InputOptions::height, "network input height").Range(8, 4096);
  s.template Add<std::vector<double>>("mean", &InputOptions::mean,
                                      "per-channel mean (RGB, pixels in [0, 255]) subtracted");
  s.template Add<std::vector<double>>("std", &InputOptions::std, "per-channel divisor (RGB) after the mean");
}

// 8-bit RGB image -> 1x3xHxW float blob of `o`.
cv::Mat InputBlob(const cv::Mat& rgb, const InputOptions& o);

}  // namespace locforge::learned

#endif  // LOCFORGE_PLUGINS_COMMON_ONNX_IMAGE_INPUT_H_

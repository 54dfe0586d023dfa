// R2D2 local features (Revaud et al., NeurIPS 2019) from the shipped ONNX
// exports (../shared/models/r2d2/README.md), run with OpenCV dnn.
//
// The extraction is the authors' reference one (README "Reference
// extraction"): an iterative image pyramid, a 3x3 maximum of repeatability
// gated by repeatability and reliability thresholds, all scales pooled, top-k.
//
// Coordinates. R2D2's own x, y are pixel indices of the network output at one
// scale times W / w ("raw", what the reference files hold; first pixel centre
// at 0). kapture output follows the SDK convention (camera.h: first pixel
// centre at (0.5, 0.5)): the centre of output pixel i at a scale of width w
// is (i + 0.5) * W / w in the original image (bilinear resize with
// align_corners = false maps pixel centres so). At scale 1 that is raw + 0.5,
// like features/sift; at coarser scales the shift is 0.5 * W / w.
#ifndef LOCFORGE_PLUGINS_FEATURES_R2D2_R2D2_H_
#define LOCFORGE_PLUGINS_FEATURES_R2D2_R2D2_H_

#include <string>
#include <vector>

#include "locforge/params.h"

namespace cv {
class Mat;
}

namespace locforge::learned {

struct R2d2Options {
  std::string model;                   // .onnx file (required; e.g. r2d2_WASF_N16.onnx).
  int top_k = 5000;                    // Keypoints kept per image, best score first (0: all).
  double min_scale = 0;                // Smallest pyramid scale.
  double max_scale = 1;                // Largest pyramid scale the network runs at.
  int min_size = 256;                  // Smallest longer side of a pyramid level.
  int max_size = 1024;                 // Largest longer side the network runs at.
  double reliability_threshold = 0.7;  // Keypoints need reliability >= this.
  double repeatability_threshold = 0.7;  // ... and repeatability >= this.
  std::string type = "r2d2";           // kapture keypoints/descriptors type (folder name).

  static void Declare(ParamSchema<R2d2Options>& s) {
    s.Add("model", &R2d2Options::model, "R2D2 ONNX model file (../shared/models/r2d2/*.onnx)")
        .Path()
        .Required();
    s.Add("top_k", &R2d2Options::top_k, "Keypoints kept per image, best score first (0: all)")
        .Min(0);
    s.Add("min_scale", &R2d2Options::min_scale, "Smallest pyramid scale").Range(0, 1);
    s.Add("max_scale", &R2d2Options::max_scale, "Largest scale the network runs at").Range(0, 1);
    s.Add("min_size", &R2d2Options::min_size, "Smallest longer image side of the pyramid").Min(1);
    s.Add("max_size", &R2d2Options::max_size, "Largest longer image side the network runs at")
        .Min(1);
    s.Add("reliability_threshold", &R2d2Options::reliability_threshold,
          "Minimum reliability of a keypoint").Range(0, 1);
    s.Add("repeatability_threshold", &R2d2Options::repeatability_threshold,
          "Minimum repeatability of a keypoint").Range(0, 1);
    s.Add("type", &R2d2Options::type, "kapture feature type (folder name)");
  }
  bool Check(std::string* why) const;
};

struct R2d2Features {
  std::vector<float> raw_keypoints;  // N x 3: x, y (R2D2's raw convention), scale 32 / s.
  std::vector<float> keypoints;      // N x 3: x, y (SDK convention), scale.
  std::vector<float> descriptors;    // N x 128, L2-normalised.
  std::vector<float> scores;         // N: reliability * repeatability, decreasing.
  double network_seconds = 0;        // Time spent in the network, all scales.
  int scales = 0;                    // Pyramid levels the network ran on.
  int count() const { return static_cast<int>(scores.size()); }
};

// Extracts R2D2 features of an 8-bit RGB image (3 channels, R first) with
// the model options.model, loaded once per thread (cv::dnn::Net is not
// thread-safe). Throws InputError when the model cannot be loaded.
R2d2Features ExtractR2d2(const cv::Mat& rgb, const R2d2Options& options);

// The R2D2 contract on the network outputs {descriptors, reliability,
// repeatability} of a level_h x level_w input: float32 1x128xhxw, 1x1xhxw,
// 1x1xhxw with h x w the input size, or one pixel less on an odd side
// (faster2d2's max pool by 2 then x2 upsampling floors odd sides).
bool OutputsFollowContract(const std::vector<cv::Mat>& outputs, int level_h, int level_w);

}  // namespace locforge::learned

#endif  // LOCFORGE_PLUGINS_FEATURES_R2D2_R2D2_H_

// ALIKE local features (Zhao et al., "ALIKE: Accurate and Lightweight
// Keypoint Detection and Descriptor Extraction", IEEE TMM 2022) with the
// authors' weights (sizes t, s, n, l), run with OpenCV dnn on the free-size
// ONNX export of export_alike.py (README.md).
//
// The extraction is the authors' (alike.py ALike.forward, soft_detect.py DKD
// with sub-pixel refinement; their demo's defaults):
//   - optional downscale so the longer side is <= max_size (cv::resize, linear,
//     as the authors' image_size_max); RGB in [0, 1], zero-padded at the bottom
//     and right to multiples of 32; the network returns a score map and a
//     dense descriptor map at full resolution, cropped back to the image;
//   - non-maximum suppression of the score map (the SuperPoint-style 5x5
//     max-pool NMS with two suppression rounds), a border of radius + 1 = 3
//     pixels (left, top) / radius = 2 (right, bottom) removed;
//   - selection: top_k > 0 keeps the top_k best NMS scores; otherwise scores >
//     scores_threshold (0.2; the map's mean when none passes), at most n_limit
//     (5000) of them, best first;
//   - soft-argmax in the 5x5 window (zero padding) with temperature 0.1:
//     position += sum(exp((s - max) / T) * offset) / sum(exp(...));
//   - score = the score map bilinearly sampled at the refined position,
//     descriptor = the per-pixel L2-normalised descriptor map bilinearly
//     sampled there (align_corners = true), L2-normalised again.
//
// Coordinates: the authors' x, y have the first pixel centre at 0 (raw); the
// kapture output adds 0.5 (SDK convention). Keypoints are returned best score
// first (the authors' order is raster order below n_limit).
#ifndef LOCFORGE_PLUGINS_FEATURES_ALIKE_ALIKE_H_
#define LOCFORGE_PLUGINS_FEATURES_ALIKE_ALIKE_H_

#include <string>
#include <vector>

#include "locforge/params.h"

namespace cv {
class Mat;
}

namespace locforge::learned {

struct AlikeOptions {
  std::string model;              // Free-size ONNX of export_alike.py (required).
  int top_k = -1;                 // > 0: the top_k best; <= 0: threshold mode.
  double scores_threshold = 0.2;  // Threshold mode: minimum score.
  int n_limit = 5000;             // Threshold mode: at most this many, best first.
  int max_size = 0;               // Longer side the network runs at (0: the image's own).
  std::string type = "alike";     // kapture keypoints/descriptors type (folder name).

  static void Declare(ParamSchema<AlikeOptions>& s) {
    s.Add("model", &AlikeOptions::model,
          "ALIKE ONNX model with a free input size (export_alike.py export; build/models/alike-n.onnx)")
        .Path()
        .Required();
    s.Add("top_k", &AlikeOptions::top_k,
          "> 0: keep the top_k best NMS scores; <= 0: threshold mode (authors' default -1)");
    s.Add("scores_threshold", &AlikeOptions::scores_threshold,
          "Threshold mode: minimum keypoint score (authors: 0.2)").Range(0, 1);
    s.Add("n_limit", &AlikeOptions::n_limit,
          "Threshold mode: keypoints kept at most, best first (authors: 5000)").Min(1);
    s.Add("max_size", &AlikeOptions::max_size,
          "Downscale so the longer side is at most this before the network (0: never)").Min(0);
    s.Add("type", &AlikeOptions::type, "kapture feature type (folder name)");
  }
  bool Check(std::string* why) const;
};

struct AlikeFeatures {
  std::vector<float> raw_keypoints;  // N x 2: x, y (the authors' convention).
  std::vector<float> keypoints;      // N x 2: x, y (SDK convention).
  std::vector<float> descriptors;    // N x dim, L2-normalised.
  std::vector<float> scores;         // N, decreasing.
  int dim = 0;                       // Descriptor size (64, 96, 128, 128 for t, s, n, l).
  double network_seconds = 0;
  int count() const { return static_cast<int>(scores.size()); }
};

// Extracts ALIKE features of an 8-bit RGB image (3 channels, R first), the
// model loaded once per thread. Throws InputError naming the model when it
// cannot be loaded or its outputs break the contract.
AlikeFeatures ExtractAlike(const cv::Mat& rgb, const AlikeOptions& options);

// The descriptor size of `model` (one run on a 32x32 image).
int AlikeDescriptorDim(const std::string& model);

}  // namespace locforge::learned

#endif  // LOCFORGE_PLUGINS_FEATURES_ALIKE_ALIKE_H_

// D2-Net (Dusmanu et al., CVPR 2019) dense features and detection from an
// ONNX model of its feature network (VGG16 up to conv4_3 with the authors'
// pool modifications; contract in README.md), the rest in C++ as the authors'
// lib/model_test.py + lib/pyramid.py (process_multiscale) +
// extract_features.py do it:
//
//   - the image is downscaled so that its longer side is <= max_edge and the
//     sum of its sides <= max_sum_edges; caffe preprocessing (BGR,
//     mean-subtracted, pixels in [0, 255]);
//   - for each scale (single: {1}; the authors' multi-scale {0.5, 1, 2}) the
//     image is resized bilinearly with align_corners (output floor(size *
//     scale)), run through the network, and the features of the previous
//     (coarser) level, upsampled bilinearly (align_corners), are added;
//   - hard detection (paper eq. 1-2): a feature D^k_ij is detected when k is
//     its channel-wise maximum and it is a 3x3 spatial local maximum, and it is
//     not on an edge (Hessian trace^2 / det <= (r + 1)^2 / r, det > 0,
//     r = edge_threshold = 5); pixels detected at a coarser level are banned;
//   - sub-pixel refinement by one Newton step on the 3x3 Hessian of D^k (the
//     HandcraftedLocalizationModule), kept when both steps are < 0.5;
//   - descriptor = the features bilinearly interpolated at the refined
//     position, L2-normalised; position in the level's pixels = 4 p + 1.5 (two
//     stride-2 pools; upscale_positions), times original / level size;
//   - score: "authors": D^k_ij / (level index + 1) (process_multiscale);
//     "soft": the soft detection score of the paper (eq. 3-5) at that pixel of
//     the level, s_ij = max_k alpha^k_ij beta^k_ij / sum_ij(...), alpha a 3x3
//     soft local max of exp(D / max D) (SoftDetectionModule), beta = D^k /
//     max_t D^t;
//   - best `top_k` scores first (0: all, in the authors' order).
//
// Coordinates: the authors' (x, y) are pixel-index coordinates (first pixel
// centre at 0); kapture output adds 0.5 (SDK convention, first pixel centre at
// (0.5, 0.5)). The third keypoint value is the authors' 1 / scale.
#ifndef LOCFORGE_PLUGINS_FEATURES_D2NET_D2NET_H_
#define LOCFORGE_PLUGINS_FEATURES_D2NET_D2NET_H_

#include <string>
#include <vector>

#include "locforge/params.h"

namespace cv {
class Mat;
}

namespace locforge::learned {

struct D2netOptions {
  std::string model;                      // .onnx file (required).
  std::string input = "image";            // Input tensor name.
  std::string output = "features";        // Output tensor name (1 x C x h x w).
  std::vector<double> scales = {1.0};     // {0.5, 1, 2}: the authors' multi-scale.
  int max_edge = 1600;                    // Longer image side limit (authors' default).
  int max_sum_edges = 2800;               // Limit of width + height (authors' default).
  double edge_threshold = 5;              // r of the edge test (authors' 5).
  std::string score = "authors";          // "authors" or "soft" (paper eq. 3-5).
  int top_k = 0;                          // Keypoints kept, best score first (0: all).
  std::vector<double> mean = {103.939, 116.779, 123.68};  // BGR caffe means.
  std::string type = "d2net";             // kapture feature type (folder name).

  static void Declare(ParamSchema<D2netOptions>& s) {
    s.Add("model", &D2netOptions::model, "D2-Net feature network ONNX file (README contract)")
        .Path()
        .Required();
    s.Add("input", &D2netOptions::input, "input tensor name (1x3xHxW float32, BGR caffe)");
    s.Add("output", &D2netOptions::output, "output tensor name (1xCxhxw dense features)");
    s.Add("scales", &D2netOptions::scales,
          "image scales, coarse to fine ([1]: single scale; [0.5, 1, 2]: the authors' multi-scale)")
        .Range(0.05, 4);
    s.Add("max_edge", &D2netOptions::max_edge, "longer image side limit (downscale)").Min(16);
    s.Add("max_sum_edges", &D2netOptions::max_sum_edges, "width + height limit (downscale)")
        .Min(32);
    s.Add("edge_threshold", &D2netOptions::edge_threshold, "edge test ratio r").Min(1);
    s.Add("score", &D2netOptions::score,
          "keypoint score: authors (feature value / (level + 1)) or soft (paper eq. 3-5)")
        .Choices({"authors", "soft"});
    s.Add("top_k", &D2netOptions::top_k, "keypoints kept, best score first (0: all)").Min(0);
    s.Add("mean", &D2netOptions::mean, "per blob channel (B, G, R), subtracted from pixels");
    s.Add("type", &D2netOptions::type, "kapture feature type (folder name)");
  }
  bool Check(std::string* why) const;
};

struct D2netFeatures {
  std::vector<float> raw_keypoints;  // N x 3: x, y (authors' pixel-index convention), 1/scale
  std::vector<float> keypoints;      // N x 3: x, y (SDK convention: raw + 0.5), 1/scale
  std::vector<float> descriptors;    // N x C, L2-normalised
  std::vector<float> scores;         // N
  int channels = 0;                  // C
  double network_seconds = 0;
  int levels = 0;
  int count() const { return static_cast<int>(scores.size()); }
};

// Extracts D2-Net features of an 8-bit RGB image.
D2netFeatures ExtractD2net(const cv::Mat& rgb, const D2netOptions& options);

}  // namespace locforge::learned

#endif  // LOCFORGE_PLUGINS_FEATURES_D2NET_D2NET_H_

// XFeat local features (Potje et al., "XFeat: Accelerated Features for
// Lightweight Image Matching", CVPR 2024) with the authors' weights, run with
// OpenCV dnn on the free-size ONNX export of export_xfeat.py (README.md).
//
// The extraction is the authors' sparse one (modules/xfeat.py,
// XFeat.detectAndCompute):
//   - the image is resized (bilinear) to the nearest smaller multiple of 32 on
//     each side, grey = mean of R, G, B in [0, 1]; the network normalises it
//     (instance normalisation) and returns, at 1/8 resolution, 64-D descriptors,
//     65 keypoint logits per 8x8 cell and a reliability map;
//   - the logits go through a softmax, the "no keypoint" bin is dropped and the
//     64 others fill the cell: a full-resolution heatmap; keypoints are its 5x5
//     local maxima above `detection_threshold` (0.05);
//   - score = heatmap x reliability, both sampled at the keypoint as the
//     authors do (grid_sample, align_corners = false, positions normalised by
//     W - 1 and H - 1; nearest for the heatmap, bilinear for reliability);
//     a keypoint at (0, 0) scores -1 (the authors' padding marker); the best
//     `top_k` with score > 0 are kept, best first;
//   - descriptors: the 1/8 map L2-normalised per pixel, sampled at the keypoint
//     with the authors' bicubic grid_sample (A = -0.75, zero padding), then
//     L2-normalised (64-D, metric L2; matched by mutual nearest neighbours).
//
// Coordinates. XFeat's own x, y are the keypoint's pixel index in the resized
// image times W / W32 ("raw", what the reference holds). kapture output
// follows the SDK convention (first pixel centre at (0.5, 0.5)): the centre of
// pixel i of the resized image, (i + 0.5) * W / W32.
#ifndef LOCFORGE_PLUGINS_FEATURES_XFEAT_XFEAT_H_
#define LOCFORGE_PLUGINS_FEATURES_XFEAT_XFEAT_H_

#include <string>
#include <vector>

#include "locforge/params.h"

namespace cv {
class Mat;
}

namespace locforge::learned {

struct XfeatOptions {
  std::string model;                 // Free-size ONNX of export_xfeat.py (required).
  int top_k = 4096;                  // Keypoints kept per image, best score first.
  double detection_threshold = 0.05; // Minimum heatmap value of a keypoint.
  int max_size = 0;                  // Longer side the network runs at (0: the image's own).
  std::string type = "xfeat";        // kapture keypoints/descriptors type (folder name).

  static void Declare(ParamSchema<XfeatOptions>& s) {
    s.Add("model", &XfeatOptions::model,
          "XFeat ONNX model with a free input size (export_xfeat.py export; build/models/xfeat.onnx)")
        .Path()
        .Required();
    s.Add("top_k", &XfeatOptions::top_k, "Keypoints kept per image, best score first (authors: 4096)")
        .Min(1);
    s.Add("detection_threshold", &XfeatOptions::detection_threshold,
          "Minimum keypoint heatmap value (authors: 0.05)").Range(0, 1);
    s.Add("max_size", &XfeatOptions::max_size,
          "Downscale (area) so the longer side is at most this before the network (0: never)")
        .Min(0);
    s.Add("type", &XfeatOptions::type, "kapture feature type (folder name)");
  }
  bool Check(std::string* why) const;
};

struct XfeatFeatures {
  std::vector<float> raw_keypoints;  // N x 2: x, y (XFeat's convention).
  std::vector<float> keypoints;      // N x 2: x, y (SDK convention).
  std::vector<float> descriptors;    // N x 64, L2-normalised.
  std::vector<float> scores;         // N, decreasing, > 0.
  int network_width = 0, network_height = 0;  // The resized image (multiples of 32).
  double network_seconds = 0;
  int count() const { return static_cast<int>(scores.size()); }
};

// Extracts XFeat features of an 8-bit RGB image (3 channels, R first), the
// model loaded once per thread. Throws InputError naming the model when it
// cannot be loaded or its outputs break the contract, or when the image is
// smaller than 32 x 32 (after max_size).
XfeatFeatures ExtractXfeat(const cv::Mat& rgb, const XfeatOptions& options);

}  // namespace locforge::learned

#endif  // LOCFORGE_PLUGINS_FEATURES_XFEAT_XFEAT_H_

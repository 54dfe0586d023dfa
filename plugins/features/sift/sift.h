// OpenCV SIFT extraction into kapture keypoints/descriptors arrays.
//
// Layout written (kapture 1.1, as COLMAP's kapture export):
//  - keypoints: float32, dsize 4: x, y, scale, orientation. x, y follow the
//    SDK's pixel convention (camera.h: first pixel centre at (0.5, 0.5)), i.e.
//    OpenCV's coordinates + 0.5, like COLMAP's SIFT. scale = OpenCV size / 2
//    (the keypoint's Gaussian sigma in pixels, COLMAP's "scale"),
//    orientation in radians (OpenCV angle, clockwise in the image).
//  - descriptors: 128 values, uint8 by default (COLMAP's conversion: the
//    L2- or RootSIFT-normalised vector x 512, clamped to 255, so COLMAP can
//    import them) or float32 (the normalised vector itself), metric L2.
#ifndef LOCFORGE_PLUGINS_FEATURES_SIFT_SIFT_H_
#define LOCFORGE_PLUGINS_FEATURES_SIFT_SIFT_H_

#include <cstdint>
#include <string>
#include <vector>

#include "locforge/params.h"

namespace cv {
class KeyPoint;
class Mat;
}

namespace locforge::sift {

struct SiftOptions {
  int max_keypoints = 8000;        // Cap after extraction, in cap_order.
  std::string cap_order = "response";  // "response" or "scale" (COLMAP's: whole levels, coarsest first).
  bool root_sift = true;           // Hellinger (RootSIFT) normalisation of descriptors.
  bool upright = false;            // One keypoint per location, orientation 0.
  int octave_layers = 3;           // OpenCV nOctaveLayers.
  double contrast_threshold = 0.04;  // OpenCV contrastThreshold (lower: more keypoints).
  double edge_threshold = 10;      // OpenCV edgeThreshold.
  double sigma = 1.6;              // Gaussian sigma of the first octave.
  int max_image_size = 0;          // Downscale so the longer side <= this (0: never).
  std::string descriptor_dtype = "uint8";  // "uint8" (x512, COLMAP) or "float32".
  std::string type = "sift";       // kapture keypoints/descriptors type (folder name).

  static void Declare(ParamSchema<SiftOptions>& s) {
    s.Add("max_keypoints", &SiftOptions::max_keypoints,
          "Keypoints kept per image, in cap_order (0: all)").Min(0);
    s.Add("cap_order", &SiftOptions::cap_order,
          "Which keypoints the cap keeps: response (the strongest) or scale (COLMAP's rule: whole "
          "DoG levels from the coarsest, down to the one that reaches the cap, kept whole)")
        .Choices({"response", "scale"});
    s.Add("root_sift", &SiftOptions::root_sift, "RootSIFT (Hellinger) descriptors");
    s.Add("upright", &SiftOptions::upright, "One orientation-free keypoint per location");
    s.Add("octave_layers", &SiftOptions::octave_layers, "Layers per octave").Range(1, 10);
    s.Add("contrast_threshold", &SiftOptions::contrast_threshold,
          "Contrast threshold of the detector").Range(0, 1);
    s.Add("edge_threshold", &SiftOptions::edge_threshold, "Edge threshold of the detector")
        .Range(1, 100);
    s.Add("sigma", &SiftOptions::sigma, "Gaussian sigma of the first octave").Range(0.5, 5);
    s.Add("max_image_size", &SiftOptions::max_image_size,
          "Downscale so the longer image side is at most this (0: never)").Min(0);
    s.Add("descriptor_dtype", &SiftOptions::descriptor_dtype,
          "uint8 (x512 like COLMAP) or float32").Choices({"uint8", "float32"});
    s.Add("type", &SiftOptions::type, "kapture feature type (folder name)");
  }
  bool Check(std::string* why) const;
};

struct SiftFeatures {
  std::vector<float> keypoints;    // N x 4
  std::vector<float> descriptors;  // N x 128, normalised (L2 or RootSIFT)
  int count() const { return static_cast<int>(keypoints.size() / 4); }
};

// Extracts SIFT on an 8-bit grey image. Deterministic for a given image.
SiftFeatures ExtractSift(const cv::Mat& gray, const SiftOptions& options);

// cap_order "scale": OpenCV keypoints (sorted strongest first) -> whole DoG
// levels from the coarsest, down to and including the level at which the
// distinct locations exceed max_locations (COLMAP's rule).
void KeepCoarsestLevels(std::vector<cv::KeyPoint>* keypoints, int max_locations);

// RootSIFT of one 128-vector in place: L1-normalise, then square root
// (the result has unit L2 norm).
void RootSiftInPlace(float* descriptor, int size);

// Descriptors as stored: uint8 = min(255, round(512 x)), else unchanged.
std::vector<uint8_t> DescriptorsToUint8(const std::vector<float>& descriptors);

}  // namespace locforge::sift

#endif  // LOCFORGE_PLUGINS_FEATURES_SIFT_SIFT_H_

#include "sift.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "locforge/error.h"
#include "locforge/kapture/features.h"

namespace locforge::sift {

namespace {

// Strongest first; ties broken by position so the order never depends on
// OpenCV's threading.
bool StrongerFirst(const cv::KeyPoint& a, const cv::KeyPoint& b) {
  if (a.response != b.response) return a.response > b.response;
  if (a.pt.y != b.pt.y) return a.pt.y < b.pt.y;
  if (a.pt.x != b.pt.x) return a.pt.x < b.pt.x;
  if (a.size != b.size) return a.size < b.size;
  return a.angle < b.angle;
}

bool SameLocation(const cv::KeyPoint& a, const cv::KeyPoint& b) {
  return a.pt == b.pt && a.size == b.size;
}

// OpenCV packs the octave (signed byte; -1: the doubled image) and the
// layer into KeyPoint::octave; the level orders keypoints by scale.
int DogLevel(const cv::KeyPoint& kp) {
  int octave = kp.octave & 255;
  if (octave >= 128) octave -= 256;
  const int layer = (kp.octave >> 8) & 255;
  return octave * 256 + layer;
}

}  // namespace

// COLMAP's cap (its CPU SIFT extraction, sift.h): whole DoG levels from the coarsest
// down to the level at which the distinct locations exceed the cap, that level
// kept whole. Large-scale keypoints repeat across viewpoints; a response cap
// keeps the many fine-scale ones of a textured image instead.
void KeepCoarsestLevels(std::vector<cv::KeyPoint>* keypoints, int max_locations) {
  std::vector<cv::KeyPoint>& k = *keypoints;
  // Stable: within a level, the strongest first (extra orientations of one
  // location stay adjacent).
  std::stable_sort(k.begin(), k.end(),
                   [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return DogLevel(a) > DogLevel(b); });
  int locations = 0;
  size_t end = 0;
  while (end < k.size() && locations <= max_locations) {
    const int level = DogLevel(k[end]);
    for (size_t first = end; end < k.size() && DogLevel(k[end]) == level; ++end)
      if (end == first || !SameLocation(k[end - 1], k[end])) ++locations;
  }
  k.resize(end);
}

bool SiftOptions::Check(std::string* why) const {
  if (!kapture::IsFeatureTypeName(type)) {
    *why = "parameter 'type': '" + type + "' is not a folder name";
    return false;
  }
  return true;
}

void RootSiftInPlace(float* d, int size) {
  double l1 = 0;
  for (int i = 0; i < size; ++i) l1 += std::abs(d[i]);
  const double inv = l1 > 0 ? 1.0 / l1 : 0.0;
  for (int i = 0; i < size; ++i) d[i] = static_cast<float>(std::sqrt(std::abs(d[i]) * inv));
}

std::vector<uint8_t> DescriptorsToUint8(const std::vector<float>& descriptors) {
  std::vector<uint8_t> out(descriptors.size());
  for (size_t i = 0; i < descriptors.size(); ++i)
    out[i] = static_cast<uint8_t>(std::min(255.0f, std::round(512.0f * descriptors[i])));
  return out;
}

// OpenCV's SIFT (4.6) works on the image doubled by a pixel-centre-aligned
// bilinear resize (pixel i -> 2 i + 0.5) and reports the doubled image's
// coordinates halved (p -> p / 2), so every keypoint is 0.25 px right of and
// below its true position, at every octave (higher octaves subsample the
// doubled image from its pixel 0); sift_test.cc KeypointsHaveNoSubpixelBias
// checks the correction. Its effect on the ground truth: README.md here.
constexpr double kOpenCvSiftOffsetPx = 0.25;

SiftFeatures ExtractSift(const cv::Mat& gray_in, const SiftOptions& o) {
  if (gray_in.empty() || gray_in.type() != CV_8UC1) throw Error("ExtractSift: expected an 8-bit grey image");
  cv::Mat gray = gray_in;
  double scale = 1.0;  // resized / original
  const int longer = std::max(gray_in.cols, gray_in.rows);
  if (o.max_image_size > 0 && longer > o.max_image_size) {
    scale = static_cast<double>(o.max_image_size) / longer;
    cv::resize(gray_in, gray, cv::Size(), scale, scale, cv::INTER_AREA);
  }
  auto sift = cv::SIFT::create(0, o.octave_layers, o.contrast_threshold, o.edge_threshold, o.sigma);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  sift->detect(gray, keypoints);
  std::sort(keypoints.begin(), keypoints.end(), StrongerFirst);
  if (o.upright) {
    // Extra orientations are the same location: keep one, at angle 0.
    std::vector<cv::KeyPoint> unique;
    for (auto kp : keypoints) {
      kp.angle = 0;
      if (std::none_of(unique.end() - std::min<size_t>(unique.size(), 4), unique.end(),
                       [&](const cv::KeyPoint& u) { return SameLocation(u, kp); }))
        unique.push_back(kp);
    }
    keypoints.swap(unique);
  }
  if (o.max_keypoints > 0 && o.cap_order == "scale")
    KeepCoarsestLevels(&keypoints, o.max_keypoints);
  else if (o.max_keypoints > 0 && static_cast<int>(keypoints.size()) > o.max_keypoints)
    keypoints.resize(o.max_keypoints);
  SiftFeatures out;
  if (keypoints.empty()) return out;
  const size_t detected = keypoints.size();
  sift->compute(gray, keypoints, descriptors);
  if (keypoints.size() != detected || descriptors.rows != static_cast<int>(detected))
    throw Error("ExtractSift: OpenCV dropped keypoints while computing descriptors");
  out.keypoints.reserve(4 * keypoints.size());
  out.descriptors.resize(128 * keypoints.size());
  for (size_t i = 0; i < keypoints.size(); ++i) {
    const cv::KeyPoint& kp = keypoints[i];
    // OpenCV pixel indices (first pixel centre at 0) minus OpenCV's own
    // offset, then +0.5 to the SDK convention; cv::resize keeps pixel
    // centres aligned, so dividing by the scale is exact.
    const double x = kp.pt.x - kOpenCvSiftOffsetPx + 0.5, y = kp.pt.y - kOpenCvSiftOffsetPx + 0.5;
    out.keypoints.push_back(static_cast<float>(x / scale));
    out.keypoints.push_back(static_cast<float>(y / scale));
    out.keypoints.push_back(static_cast<float>(kp.size / 2.0 / scale));
    out.keypoints.push_back(static_cast<float>(kp.angle * M_PI / 180.0));
    float* d = &out.descriptors[128 * i];
    const float* src = descriptors.ptr<float>(static_cast<int>(i));
    std::copy(src, src + 128, d);
    if (o.root_sift) {
      RootSiftInPlace(d, 128);
    } else {
      double n2 = 0;
      for (int k = 0; k < 128; ++k) n2 += double(d[k]) * d[k];
      const float inv = n2 > 0 ? static_cast<float>(1.0 / std::sqrt(n2)) : 0.f;
      for (int k = 0; k < 128; ++k) d[k] *= inv;
    }
  }
  return out;
}

}  // namespace locforge::sift

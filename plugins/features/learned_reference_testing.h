// Test helpers shared by the learned features' reference tests (xfeat, alike, r2d2):
// the recipe scripts' stored reference extractions (raw float32 keypoints,
// float16 descriptors, a "key value" .txt) and the comparison of an
// extraction with them.
#ifndef LOCFORGE_PLUGINS_FEATURES_LEARNED_REFERENCE_TESTING_H_
#define LOCFORGE_PLUGINS_FEATURES_LEARNED_REFERENCE_TESTING_H_

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "testing.h"

// The exported model (build/models, written by the build when python3-torch
// is there); skip without it, fail under LOCFORGE_REQUIRE_SHARED=1.
#define LOCFORGE_LEARNED_MODEL_OR_SKIP(var, file)                                            \
  const std::filesystem::path var = std::filesystem::path(LOCFORGE_LEARNED_MODEL_DIR) / (file); \
  if (!std::filesystem::exists(var)) {                                                       \
    if (::locforge::testing::SharedRequired())                                               \
      FAIL() << var << " was not exported (needs python3-torch, python3-onnx and ../shared) " \
                "and LOCFORGE_REQUIRE_SHARED=1";                                             \
    GTEST_SKIP() << var << " was not exported: install python3-torch and rebuild";           \
  }

namespace locforge::learned::reference {

template <typename T>
std::vector<T> ReadRaw(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  EXPECT_TRUE(in.good()) << file;
  in.seekg(0, std::ios::end);
  std::vector<T> v(static_cast<size_t>(in.tellg()) / sizeof(T));
  in.seekg(0);
  in.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(T)));
  return v;
}

inline std::vector<float> ReadHalf(const std::filesystem::path& file) {
  const std::vector<uint16_t> h = ReadRaw<uint16_t>(file);
  cv::Mat half(1, static_cast<int>(h.size()), CV_16F, const_cast<uint16_t*>(h.data())), full;
  half.convertTo(full, CV_32F);
  return std::vector<float>(full.begin<float>(), full.end<float>());
}

// "key value..." lines of the reference's .txt.
inline std::map<std::string, std::string> ReadMeta(const std::filesystem::path& file) {
  std::ifstream in(file);
  EXPECT_TRUE(in.good()) << file;
  std::map<std::string, std::string> meta;
  std::string line;
  while (std::getline(in, line)) {
    const size_t space = line.find(' ');
    if (space != std::string::npos) meta[line.substr(0, space)] = line.substr(space + 1);
  }
  return meta;
}

// The reference image: the crop x,y,w,h of the .txt, 8-bit RGB, checked
// against the decoded pixel sum PIL gave the recipe script.
inline cv::Mat ReferenceImage(const std::filesystem::path& image, const std::map<std::string, std::string>& meta) {
  const cv::Mat bgr = cv::imread(image.string(), cv::IMREAD_COLOR);
  EXPECT_FALSE(bgr.empty()) << image;
  int x, y, w, h;
  char comma;
  std::istringstream(meta.at("crop")) >> x >> comma >> y >> comma >> w >> comma >> h;
  cv::Mat rgb;
  cv::cvtColor(bgr(cv::Rect(x, y, w, h)), rgb, cv::COLOR_BGR2RGB);
  const cv::Scalar sum = cv::sum(rgb);
  EXPECT_EQ(static_cast<long long>(sum[0] + sum[1] + sum[2]), std::stoll(meta.at("pixel_sum")))
      << "OpenCV decodes " << image << " differently from the recipe script's PIL";
  return rgb;
}

struct ReferenceAgreement {
  int checked = 0;       // our best keypoints compared
  int matched = 0;       // of them, at a reference keypoint within 1 px
  int cosine_ok = 0;     // of those, with descriptor cosine >= 0.99
  double worst_cosine = 1, max_distance = 0;
};

// Each of our `checked` best keypoints (raw network coordinates, x y pairs):
// the nearest reference keypoint within 1 px, and its descriptor's cosine
// (both sets L2-normalised, `dim`-D).
inline ReferenceAgreement CompareWithReference(const std::vector<float>& raw_keypoints,
                                               const std::vector<float>& descriptors, int dim,
                                               const std::vector<float>& ref_kpt,
                                               const std::vector<float>& ref_desc, int checked) {
  ReferenceAgreement a;
  a.checked = checked;
  const size_t stored = ref_kpt.size() / 2;
  for (int i = 0; i < checked; ++i) {
    const float* p = &raw_keypoints[2 * i];
    int best = -1;
    double best_d2 = 1.0 + 1e-6;
    for (size_t j = 0; j < stored; ++j) {
      const double dx = p[0] - ref_kpt[2 * j], dy = p[1] - ref_kpt[2 * j + 1];
      if (dx * dx + dy * dy <= best_d2) best_d2 = dx * dx + dy * dy, best = static_cast<int>(j);
    }
    if (best < 0) continue;
    ++a.matched;
    a.max_distance = std::max(a.max_distance, std::sqrt(best_d2));
    double dot = 0;
    for (int k = 0; k < dim; ++k) dot += double(descriptors[dim * i + k]) * ref_desc[dim * best + k];
    a.worst_cosine = std::min(a.worst_cosine, dot);
    a.cosine_ok += dot >= 0.99;
  }
  return a;
}

}  // namespace locforge::learned::reference

#endif  // LOCFORGE_PLUGINS_FEATURES_LEARNED_REFERENCE_TESTING_H_

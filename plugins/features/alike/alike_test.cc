// ALIKE (t, s, n, l) against the authors' extraction computed in PyTorch by
// the recipe script (export_alike.py reference, stored in testdata/) on a
// crop of a real photograph (Strecha fountain-P11, ../shared/data/localization).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "alike.h"
#include "testing.h"

namespace locforge::learned {
namespace {

namespace fs = std::filesystem;

#define LOCFORGE_LEARNED_MODEL_OR_SKIP(var, file)                                            \
  const fs::path var = fs::path(LOCFORGE_LEARNED_MODEL_DIR) / (file);                        \
  if (!fs::exists(var)) {                                                                    \
    if (::locforge::testing::SharedRequired())                                               \
      FAIL() << var << " was not exported (needs python3-torch, python3-onnx and ../shared) " \
                "and LOCFORGE_REQUIRE_SHARED=1";                                             \
    GTEST_SKIP() << var << " was not exported: install python3-torch and rebuild";           \
  }

template <typename T>
std::vector<T> ReadRaw(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  EXPECT_TRUE(in.good()) << file;
  in.seekg(0, std::ios::end);
  std::vector<T> v(static_cast<size_t>(in.tellg()) / sizeof(T));
  in.seekg(0);
  in.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(T)));
  return v;
}

std::vector<float> ReadHalf(const fs::path& file) {
  const std::vector<uint16_t> h = ReadRaw<uint16_t>(file);
  cv::Mat half(1, static_cast<int>(h.size()), CV_16F, const_cast<uint16_t*>(h.data())), full;
  half.convertTo(full, CV_32F);
  return std::vector<float>(full.begin<float>(), full.end<float>());
}

std::map<std::string, std::string> ReadMeta(const fs::path& file) {
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

cv::Mat ReferenceImage(const fs::path& image, const std::map<std::string, std::string>& meta) {
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

class AlikeReference : public ::testing::TestWithParam<std::string> {};

TEST_P(AlikeReference, ReproducesTheAuthorsExtractionOnARealPhotograph) {
  const std::string size = GetParam();
  LOCFORGE_SHARED_PATH_OR_SKIP(image, "data/localization/strecha_fountain-P11/mapping/sensors/records_data/0000.jpg");
  LOCFORGE_LEARNED_MODEL_OR_SKIP(model, "alike-" + size + ".onnx");
  const fs::path stem = fs::path(LOCFORGE_ALIKE_TESTDATA) / ("alike-" + size);
  const auto meta = ReadMeta(stem.string() + ".txt");
  const cv::Mat rgb = ReferenceImage(image, meta);
  ASSERT_EQ(rgb.cols, 1000);  // padded to 1024x704 for the network
  AlikeOptions o;  // the authors' demo defaults
  o.model = model.string();
  std::string why;
  ASSERT_TRUE(o.Check(&why)) << why;
  const auto start = std::chrono::steady_clock::now();
  const AlikeFeatures f = ExtractAlike(rgb, o);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const int dim = std::stoi(meta.at("dim"));
  EXPECT_EQ(f.dim, dim);
  const std::vector<float> ref_kpt = ReadRaw<float>(stem.string() + ".kpt.f32");
  const std::vector<float> ref_desc = ReadHalf(stem.string() + ".desc.f16");
  const size_t stored = ref_kpt.size() / 2;
  ASSERT_EQ(stored, static_cast<size_t>(std::stoi(meta.at("stored"))));
  ASSERT_EQ(ref_desc.size(), stored * dim);
  EXPECT_EQ(f.count(), std::stoi(meta.at("keypoints")));
  for (int i = 1; i < f.count(); ++i) ASSERT_LE(f.scores[i], f.scores[i - 1]);

  const int checked = static_cast<int>(stored) * 9 / 10;
  int matched = 0, cosine_ok = 0;
  double worst_cosine = 1, max_distance = 0;
  for (int i = 0; i < checked; ++i) {
    const float* p = &f.raw_keypoints[2 * i];
    int best = -1;
    double best_d2 = 1.0 + 1e-6;
    for (size_t j = 0; j < stored; ++j) {
      const double dx = p[0] - ref_kpt[2 * j], dy = p[1] - ref_kpt[2 * j + 1];
      if (dx * dx + dy * dy <= best_d2) best_d2 = dx * dx + dy * dy, best = static_cast<int>(j);
    }
    if (best < 0) continue;
    ++matched;
    max_distance = std::max(max_distance, std::sqrt(best_d2));
    double dot = 0;
    for (int k = 0; k < dim; ++k) dot += double(f.descriptors[dim * i + k]) * ref_desc[dim * best + k];
    worst_cosine = std::min(worst_cosine, dot);
    cosine_ok += dot >= 0.99;
  }
  std::cout << "alike-" << size << " on fountain-P11 0000.jpg [" << meta.at("crop") << "]: "
            << f.count() << " keypoints (" << dim << "-D), network " << f.network_seconds
            << " s, extraction " << seconds << " s; " << matched << " / " << checked
            << " of our best at a reference keypoint (<= 1 px, max " << max_distance << " px), "
            << cosine_ok << " with descriptor cosine >= 0.99 (worst " << worst_cosine << ")\n";
  EXPECT_GE(matched, checked * 99 / 100);
  EXPECT_GE(cosine_ok, checked * 99 / 100);
  EXPECT_LT(max_distance, 0.01);  // sub-pixel positions, not just the same pixel
  for (int i = 0; i < f.count(); ++i) {
    ASSERT_FLOAT_EQ(f.keypoints[2 * i], f.raw_keypoints[2 * i] + 0.5f);
    // NMS keeps pixels 3 .. w - 3; the refinement moves them by at most 2 px.
    ASSERT_TRUE(f.raw_keypoints[2 * i] >= 1 && f.raw_keypoints[2 * i] <= 999 &&
                f.raw_keypoints[2 * i + 1] >= 1 && f.raw_keypoints[2 * i + 1] <= 699);
  }
}

INSTANTIATE_TEST_SUITE_P(Sizes, AlikeReference, ::testing::Values("t", "s", "n", "l"));

TEST(Alike, TopKModeAndMaxSize) {
  LOCFORGE_SHARED_PATH_OR_SKIP(image, "data/localization/strecha_fountain-P11/mapping/sensors/records_data/0000.jpg");
  LOCFORGE_LEARNED_MODEL_OR_SKIP(model, "alike-t.onnx");
  cv::Mat rgb;
  cv::cvtColor(cv::imread(image.string(), cv::IMREAD_COLOR), rgb, cv::COLOR_BGR2RGB);
  ASSERT_EQ(rgb.cols, 1536);
  AlikeOptions o;
  o.model = model.string();
  o.top_k = 300;
  o.max_size = 640;  // 640x427: the authors' image_size_max, keypoints back in 1536x1024
  const AlikeFeatures f = ExtractAlike(rgb, o);
  ASSERT_EQ(f.count(), 300);
  EXPECT_EQ(f.dim, 64);
  for (int i = 0; i < f.count(); ++i) {
    if (i > 0) ASSERT_LE(f.scores[i], f.scores[i - 1]);
    ASSERT_TRUE(f.keypoints[2 * i] > 0 && f.keypoints[2 * i] < 1536 && f.keypoints[2 * i + 1] > 0 &&
                f.keypoints[2 * i + 1] < 1024);
  }
  // The same points at 1024 px sit within a few pixels of most of these
  // (both mapped back to 1536x1024).
  o.max_size = 1024;
  o.top_k = 3000;
  const AlikeFeatures g = ExtractAlike(rgb, o);
  int near = 0;
  for (int i = 0; i < f.count(); ++i)
    for (int j = 0; j < g.count(); ++j)
      if (std::hypot(f.keypoints[2 * i] - g.keypoints[2 * j], f.keypoints[2 * i + 1] - g.keypoints[2 * j + 1]) < 4) {
        ++near;
        break;
      }
  std::cout << "alike-t at 640 px: " << near << " / 300 within 4 px of a keypoint found at 1024 px\n";
  EXPECT_GT(near, 150);
}

TEST(Alike, OptionsAndMissingModel) {
  AlikeOptions o;
  std::string why;
  EXPECT_FALSE(o.Check(&why));
  EXPECT_NE(why.find("model"), std::string::npos);
  o.model = "/nonexistent/alike-n.onnx";
  EXPECT_TRUE(o.Check(&why)) << why;
  o.type = "../x";
  EXPECT_FALSE(o.Check(&why));
  o.type = "alike";
  try {
    ExtractAlike(cv::Mat(64, 64, CV_8UC3, cv::Scalar(1, 2, 3)), o);
    FAIL() << "no error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/alike-n.onnx"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace locforge::learned

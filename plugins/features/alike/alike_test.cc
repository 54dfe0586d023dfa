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
#include "learned_reference_testing.h"
#include "testing.h"

namespace locforge::learned {
namespace {

namespace fs = std::filesystem;
using namespace ::locforge::learned::reference;  // learned_reference_testing.h

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

  const ReferenceAgreement a =
      CompareWithReference(f.raw_keypoints, f.descriptors, dim, ref_kpt, ref_desc, static_cast<int>(stored) * 9 / 10);
  std::cout << "alike-" << size << " on fountain-P11 0000.jpg [" << meta.at("crop") << "]: "
            << f.count() << " keypoints (" << dim << "-D), network " << f.network_seconds
            << " s, extraction " << seconds << " s; " << a.matched << " / " << a.checked
            << " of our best at a reference keypoint (<= 1 px, max " << a.max_distance << " px), "
            << a.cosine_ok << " with descriptor cosine >= 0.99 (worst " << a.worst_cosine << ")\n";
  EXPECT_GE(a.matched, a.checked * 99 / 100);
  EXPECT_GE(a.cosine_ok, a.checked * 99 / 100);
  EXPECT_LT(a.max_distance, 0.01);  // sub-pixel positions, not just the same pixel
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

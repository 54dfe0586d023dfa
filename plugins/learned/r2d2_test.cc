// R2D2 against the authors' own output (../shared/models/r2d2/reference):
// the same keypoints (pixel and scale) and the same descriptors.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "r2d2.h"
#include "testing.h"

namespace locforge::learned {
namespace {

std::vector<float> ReadFloats(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  EXPECT_TRUE(in.good()) << file;
  in.seekg(0, std::ios::end);
  std::vector<float> v(static_cast<size_t>(in.tellg()) / sizeof(float));
  in.seekg(0);
  in.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(float)));
  return v;
}

TEST(R2d2, ReproducesTheAuthorsExtractionOnBoat) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, "models/r2d2");
  const cv::Mat bgr = cv::imread((dir / "reference" / "boat.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(bgr.empty());
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  R2d2Options options;
  options.model = (dir / "r2d2_WASF_N16.onnx").string();
  options.top_k = 5000;
  std::string why;
  ASSERT_TRUE(options.Check(&why)) << why;

  const auto start = std::chrono::steady_clock::now();
  const R2d2Features f = ExtractR2d2(rgb, options);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const std::vector<float> ref_kpt = ReadFloats(dir / "reference" / "boat.r2d2_WASF_N16.kpt");
  const std::vector<float> ref_desc = ReadFloats(dir / "reference" / "boat.r2d2_WASF_N16.desc");
  ASSERT_EQ(ref_kpt.size(), 5000u * 3);
  ASSERT_EQ(ref_desc.size(), 5000u * 128);
  ASSERT_EQ(f.count(), 5000);
  for (int i = 1; i < f.count(); ++i) ASSERT_LE(f.scores[i], f.scores[i - 1]);

  // Each of our 1000 best: the nearest reference keypoint of the same scale.
  const int checked = 1000;
  int matched = 0;
  std::vector<double> cosines;
  for (int i = 0; i < checked; ++i) {
    const float* p = &f.raw_keypoints[3 * i];
    int best = -1;
    double best_d2 = 1.0 + 1e-6;
    for (int j = 0; j < 5000; ++j) {
      const float* q = &ref_kpt[3 * j];
      if (std::abs(p[2] - q[2]) > 1e-3f * q[2]) continue;
      const double d2 = double(p[0] - q[0]) * (p[0] - q[0]) + double(p[1] - q[1]) * (p[1] - q[1]);
      if (d2 <= best_d2) best_d2 = d2, best = j;
    }
    if (best < 0) continue;
    ++matched;
    double dot = 0, na = 0, nb = 0;
    for (int k = 0; k < 128; ++k) {
      const double a = f.descriptors[128 * i + k], b = ref_desc[128 * best + k];
      dot += a * b, na += a * a, nb += b * b;
    }
    cosines.push_back(dot / std::sqrt(na * nb));
  }
  ASSERT_FALSE(cosines.empty());
  std::nth_element(cosines.begin(), cosines.begin() + cosines.size() / 2, cosines.end());
  const double median_cosine = cosines[cosines.size() / 2];
  const double fraction = static_cast<double>(matched) / checked;
  std::cout << "boat 512x512: " << f.scales << " scales, network " << f.network_seconds
            << " s, extraction " << seconds << " s; " << 100 * fraction
            << " % of the top " << checked << " at a reference keypoint (1 px, same scale), "
            << "median descriptor cosine " << median_cosine << "\n";
  EXPECT_GE(fraction, 0.95);
  EXPECT_GT(median_cosine, 0.99);

  // SDK coordinates: pixel centres, i.e. raw + 0.5 at scale 1 (scale 32).
  for (int i = 0; i < f.count(); ++i) {
    const float ratio = 32.0f / f.raw_keypoints[3 * i + 2];  // = s
    EXPECT_NEAR(f.keypoints[3 * i], f.raw_keypoints[3 * i] + 0.5f / ratio, 0.02f / ratio);
    if (HasFailure()) break;
  }
}

TEST(R2d2, OptionsRequireAModelAndAFolderName) {
  R2d2Options o;
  std::string why;
  EXPECT_FALSE(o.Check(&why));
  EXPECT_NE(why.find("model"), std::string::npos);
  o.model = "x.onnx";
  EXPECT_TRUE(o.Check(&why)) << why;
  o.type = "a/b";
  EXPECT_FALSE(o.Check(&why));
}

TEST(R2d2, MissingModelIsAnInputErrorNamingIt) {
  cv::Mat rgb(64, 64, CV_8UC3, cv::Scalar(10, 20, 30));
  R2d2Options o;
  o.model = "/nonexistent/model.onnx";
  try {
    ExtractR2d2(rgb, o);
    FAIL() << "no error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/model.onnx"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace locforge::learned

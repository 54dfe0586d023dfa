// SIFT with known answers: features of an image and of its warp by a known
// homography match at the homography's locations; the stage through the
// runtime: cap, layout, import of the sample's R2D2 features, conformance.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "locforge/kapture/kapture.h"
#include "locforge/runtime/registry.h"
#include "locforge/testkit.h"
#include "sift.h"
#include "testing.h"

namespace locforge::sift {
namespace {

namespace k = locforge::kapture;

// Blobs, rectangles and blurred noise: corners and blobs at every scale.
cv::Mat TexturedImage(int width, int height, uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat noise(height / 8, width / 8, CV_8UC1);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 255);
  cv::Mat image;
  cv::resize(noise, image, cv::Size(width, height), 0, 0, cv::INTER_CUBIC);
  for (int i = 0; i < 80; ++i) {
    const cv::Point c(rng.uniform(0, width), rng.uniform(0, height));
    const int r = rng.uniform(3, 25);
    if (i % 2)
      cv::circle(image, c, r, cv::Scalar(rng.uniform(0, 255)), -1, cv::LINE_AA);
    else
      cv::rectangle(image, c, c + cv::Point(r * 2, r), cv::Scalar(rng.uniform(0, 255)), -1);
  }
  cv::GaussianBlur(image, image, cv::Size(0, 0), 1.0);
  return image;
}

cv::Mat ToMat(const std::vector<float>& d) {
  return cv::Mat(static_cast<int>(d.size() / 128), 128, CV_32F, const_cast<float*>(d.data())).clone();
}

struct WarpResult {
  int matches = 0;
  double fraction_within_2px = 0;
};

WarpResult MatchUnderHomography(const SiftOptions& options, const cv::Matx33d& H) {
  const cv::Mat a = TexturedImage(640, 480, 7);
  cv::Mat b;
  cv::warpPerspective(a, b, H, a.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  const SiftFeatures fa = ExtractSift(a, options), fb = ExtractSift(b, options);
  cv::BFMatcher matcher(cv::NORM_L2, /*crossCheck=*/true);
  std::vector<cv::DMatch> matches;
  matcher.match(ToMat(fa.descriptors), ToMat(fb.descriptors), matches);
  WarpResult r;
  int good = 0;
  for (const auto& m : matches) {
    // Keypoints are in the SDK convention (pixel centre at +0.5), OpenCV's
    // warp in pixel indices: shift, map, shift back.
    const cv::Vec3d p(fa.keypoints[4 * m.queryIdx] - 0.5, fa.keypoints[4 * m.queryIdx + 1] - 0.5, 1);
    const cv::Vec3d q = H * p;
    const double dx = q[0] / q[2] + 0.5 - fb.keypoints[4 * m.trainIdx];
    const double dy = q[1] / q[2] + 0.5 - fb.keypoints[4 * m.trainIdx + 1];
    const double px = p[0], py = p[1];
    // Only points whose image stays inside b (outside, b holds reflections).
    const double qx = q[0] / q[2], qy = q[1] / q[2];
    if (qx < 8 || qy < 8 || qx > 632 || qy > 472 || px < 0 || py < 0) continue;
    ++r.matches;
    if (dx * dx + dy * dy <= 4.0) ++good;
  }
  r.fraction_within_2px = r.matches ? static_cast<double>(good) / r.matches : 0;
  return r;
}

TEST(Sift, MatchesLandWhereAKnownHomographySendsThem) {
  // Rotation by 20 deg, scale 0.9, some perspective.
  const double c = std::cos(0.35), s = std::sin(0.35);
  const cv::Matx33d H(0.9 * c, -0.9 * s, 120, 0.9 * s, 0.9 * c, -40, 1e-4, -5e-5, 1);
  SiftOptions options;
  const WarpResult r = MatchUnderHomography(options, H);
  std::cout << "homography warp: " << r.matches << " mutual matches, "
            << 100 * r.fraction_within_2px << " % within 2 px\n";
  EXPECT_GT(r.matches, 200);
  EXPECT_GT(r.fraction_within_2px, 0.9);
}

TEST(Sift, UprightMatchesUnderTranslationAndScale) {
  const cv::Matx33d H(1.1, 0, -20, 0, 1.1, -15, 0, 0, 1);
  SiftOptions options;
  options.upright = true;
  const WarpResult r = MatchUnderHomography(options, H);
  std::cout << "upright, scale 1.1: " << r.matches << " matches, "
            << 100 * r.fraction_within_2px << " % within 2 px\n";
  EXPECT_GT(r.matches, 200);
  EXPECT_GT(r.fraction_within_2px, 0.9);
}

TEST(Sift, CapIsExactAndKeepsStrongest) {
  const cv::Mat image = TexturedImage(640, 480, 3);
  SiftOptions all;
  all.max_keypoints = 0;
  SiftOptions capped;
  capped.max_keypoints = 100;
  const SiftFeatures fa = ExtractSift(image, all), fc = ExtractSift(image, capped);
  ASSERT_GT(fa.count(), 100);
  EXPECT_EQ(fc.count(), 100);
  // The capped set is the first 100 of the full one (same order).
  for (int i = 0; i < 400; ++i) EXPECT_EQ(fa.keypoints[i], fc.keypoints[i]) << i;
}

// OpenCV's packing of a keypoint's octave (signed byte) and layer.
cv::KeyPoint AtLevel(float x, int octave, int layer, float angle = 0) {
  cv::KeyPoint kp(cv::Point2f(x, 0), 2.0f * (octave + 2), angle, 1.0f);
  kp.octave = (octave & 255) | (layer << 8);
  return kp;
}

TEST(Sift, ScaleCapKeepsWholeLevelsFromTheCoarsest) {
  // Finest level first, as a response sort could leave them: octave -1 (the
  // doubled image) layer 1: 10 locations; octave 0 layer 2: 4; octave 1
  // layer 1: 3 locations, one with a second orientation.
  std::vector<cv::KeyPoint> k;
  for (int i = 0; i < 10; ++i) k.push_back(AtLevel(i, -1, 1));
  for (int i = 0; i < 4; ++i) k.push_back(AtLevel(100 + i, 0, 2));
  for (int i = 0; i < 3; ++i) k.push_back(AtLevel(200 + i, 1, 1));
  k.push_back(AtLevel(202, 1, 1, 90));
  std::vector<cv::KeyPoint> five = k, seven = k;
  // Cap 5: octave 1 (3 locations) then octave 0 reaches 7 > 5, kept whole.
  KeepCoarsestLevels(&five, 5);
  ASSERT_EQ(five.size(), 8u);
  for (int i = 0; i < 4; ++i) EXPECT_GE(five[i].pt.x, 200) << i;
  for (int i = 4; i < 8; ++i) EXPECT_GE(five[i].pt.x, 100) << i;
  // Cap 7: 7 locations do not exceed it, so the finest level comes too.
  KeepCoarsestLevels(&seven, 7);
  EXPECT_EQ(seven.size(), k.size());
}

TEST(Sift, ScaleCapKeepsLargerKeypointsOfARealExtraction) {
  const cv::Mat image = TexturedImage(640, 480, 3);
  SiftOptions all, by_scale;
  all.max_keypoints = 0;
  by_scale.max_keypoints = 100;
  by_scale.cap_order = "scale";
  const SiftFeatures fa = ExtractSift(image, all), fs = ExtractSift(image, by_scale);
  ASSERT_GT(fa.count(), 400);
  ASSERT_GE(fs.count(), 100);
  ASSERT_LT(fs.count(), fa.count());
  // Every kept keypoint is one of the full set, and the kept are the large
  // ones: the smallest kept scale is above the median of the full set.
  std::vector<float> scales;
  for (int i = 0; i < fa.count(); ++i) scales.push_back(fa.keypoints[4 * i + 2]);
  std::nth_element(scales.begin(), scales.begin() + scales.size() / 2, scales.end());
  float smallest_kept = 1e9f;
  for (int i = 0; i < fs.count(); ++i) {
    smallest_kept = std::min(smallest_kept, fs.keypoints[4 * i + 2]);
    bool found = false;
    for (int j = 0; j < fa.count() && !found; ++j)
      found = std::equal(&fs.keypoints[4 * i], &fs.keypoints[4 * i + 4], &fa.keypoints[4 * j]);
    EXPECT_TRUE(found) << i;
  }
  EXPECT_GT(smallest_kept, scales[scales.size() / 2]);
}

TEST(Sift, RootSiftHasUnitL2Norm) {
  const cv::Mat image = TexturedImage(320, 240, 5);
  const SiftFeatures f = ExtractSift(image, SiftOptions{});
  ASSERT_GT(f.count(), 10);
  for (int i = 0; i < f.count(); ++i) {
    double n = 0;
    for (int j = 0; j < 128; ++j) n += double(f.descriptors[128 * i + j]) * f.descriptors[128 * i + j];
    EXPECT_NEAR(n, 1.0, 1e-4);
  }
}

TEST(Sift, DownscaledImageKeepsOriginalCoordinates) {
  const cv::Mat image = TexturedImage(640, 480, 9);
  SiftOptions full, half;
  full.max_keypoints = 300;
  half.max_keypoints = 300;
  half.max_image_size = 320;
  const SiftFeatures ff = ExtractSift(image, full), fh = ExtractSift(image, half);
  cv::BFMatcher matcher(cv::NORM_L2, true);
  std::vector<cv::DMatch> matches;
  matcher.match(ToMat(fh.descriptors), ToMat(ff.descriptors), matches);
  int close = 0;
  for (const auto& m : matches) {
    const double dx = fh.keypoints[4 * m.queryIdx] - ff.keypoints[4 * m.trainIdx];
    const double dy = fh.keypoints[4 * m.queryIdx + 1] - ff.keypoints[4 * m.trainIdx + 1];
    close += dx * dx + dy * dy < 9.0;
  }
  EXPECT_GT(matches.size(), 50u);
  EXPECT_GT(close, 0.8 * matches.size());
}

// Gaussian blobs at known sub-pixel centres (pixel indices cx, cy; SDK
// convention cx + 0.5): the mean offset of the nearest keypoint over many
// sub-pixel phases is the extractor's bias (OpenCV alone: +0.25 px in x and y).
struct Bias {
  int found = 0;
  double mean_dx = 0, mean_dy = 0;
};

Bias MeasureBlobBias(const SiftOptions& options) {
  cv::Mat image(480, 640, CV_8UC1, cv::Scalar(40));
  cv::Mat acc(image.size(), CV_64F, cv::Scalar(0));
  std::vector<cv::Point2d> centres;
  cv::RNG rng(11);
  for (int gy = 0; gy < 6; ++gy)
    for (int gx = 0; gx < 8; ++gx)
      centres.emplace_back(40 + 80 * gx + rng.uniform(-0.5, 0.5), 40 + 80 * gy + rng.uniform(-0.5, 0.5));
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x) {
      double v = 0;
      for (const auto& c : centres) {
        const double r2 = (x - c.x) * (x - c.x) + (y - c.y) * (y - c.y);
        if (r2 < 900) v += std::exp(-r2 / (2 * 4.0 * 4.0));
      }
      acc.at<double>(y, x) = v;
    }
  acc.convertTo(image, CV_8UC1, 180, 40);
  const SiftFeatures f = ExtractSift(image, options);
  Bias b;
  for (const auto& c : centres) {
    double best = 1.5, dx = 0, dy = 0;  // a blob's keypoint lies within 1.5 px
    for (int i = 0; i < f.count(); ++i) {
      const double ex = f.keypoints[4 * i] - (c.x + 0.5), ey = f.keypoints[4 * i + 1] - (c.y + 0.5);
      if (std::hypot(ex, ey) < best) best = std::hypot(ex, ey), dx = ex, dy = ey;
    }
    if (best < 1.5) ++b.found, b.mean_dx += dx, b.mean_dy += dy;
  }
  if (b.found) b.mean_dx /= b.found, b.mean_dy /= b.found;
  return b;
}

TEST(Sift, KeypointsHaveNoSubpixelBias) {
  const Bias full = MeasureBlobBias(SiftOptions{});
  EXPECT_GE(full.found, 44);
  EXPECT_LT(std::abs(full.mean_dx), 0.05) << full.mean_dx;
  EXPECT_LT(std::abs(full.mean_dy), 0.05) << full.mean_dy;
  SiftOptions half;
  half.max_image_size = 320;  // keypoints found at half size, reported at full size
  const Bias h = MeasureBlobBias(half);
  EXPECT_GE(h.found, 44);
  EXPECT_LT(std::abs(h.mean_dx), 0.1) << h.mean_dx;
  EXPECT_LT(std::abs(h.mean_dy), 0.1) << h.mean_dy;
}

// ------------------------------------------------------------ the stages

fs::path MakeDataset(const fs::path& root, int images) {
  fs::create_directories(root / "sensors/records_data/cam");
  std::string records = "# kapture format: 1.1\n# timestamp, device_id, image_path\n";
  for (int i = 0; i < images; ++i) {
    const std::string name = "cam/" + std::to_string(i) + ".png";
    cv::imwrite((root / "sensors/records_data" / name).string(), TexturedImage(320, 240, 20 + i));
    records += std::to_string(i) + ", cam0, " + name + "\n";
  }
  WriteFileAtomic(root / "sensors/records_camera.txt", records);
  WriteFileAtomic(root / "sensors/sensors.txt",
                  "# kapture format: 1.1\ncam0, , camera, PINHOLE, 320, 240, 300, 300, 160, 120\n");
  return root;
}

TEST(SiftStage, WritesKaptureFeaturesWithTheCap) {
  const fs::path tmp = locforge::testing::MakeTempDir("sift_stage");
  const fs::path dataset = MakeDataset(tmp / "data", 3);
  runtime::Registry registry;
  ASSERT_TRUE(registry.LoadFile(LOCFORGE_FEATURES_PLUGIN_FILE));
  const auto* stage = registry.Find("features/sift");
  ASSERT_NE(stage, nullptr);
  runtime::StageInstance instance(*stage, runtime::CheckStageParams(*stage, {{"max_keypoints", "50"}}));
  runtime::RunOptions run;
  run.workspace = tmp;
  run.output_dir = tmp / "out";
  run.inputs = {{"images", "kapture.dataset", dataset}};
  run.threads = 2;
  const auto result = instance.Run(run);
  EXPECT_TRUE(result.complete);
  k::Kapture out(tmp / "out");
  ASSERT_TRUE(out.HasFeatureType(k::FeatureKind::kKeypoints, "sift"));
  const auto& info = out.GetFeatureSet(k::FeatureKind::kDescriptors, "sift").info;
  EXPECT_EQ(info.dtype, k::DType::kUint8);
  EXPECT_EQ(info.dsize, 128);
  EXPECT_EQ(info.keypoints_type, "sift");
  const auto images = out.FeatureImages(k::FeatureKind::kKeypoints, "sift");
  ASSERT_EQ(images.size(), 3u);
  for (const auto& image : images) {
    EXPECT_EQ(out.ReadKeypoints("sift", image).rows, 50);
    EXPECT_EQ(out.ReadDescriptors("sift", image).rows, 50);
  }
  fs::remove_all(tmp);
}

TEST(SiftStage, UnreadableImageIsAnInputErrorNamingIt) {
  const fs::path tmp = locforge::testing::MakeTempDir("sift_bad");
  const fs::path dataset = MakeDataset(tmp / "data", 1);
  WriteFileAtomic(dataset / "sensors/records_data/cam/0.png", "not a png");
  runtime::Registry registry;
  ASSERT_TRUE(registry.LoadFile(LOCFORGE_FEATURES_PLUGIN_FILE));
  const auto* stage = registry.Find("features/sift");
  runtime::StageInstance instance(*stage, runtime::CheckStageParams(*stage, {}));
  runtime::RunOptions run;
  run.workspace = tmp;
  run.output_dir = tmp / "out";
  run.inputs = {{"images", "kapture.dataset", dataset}};
  try {
    instance.Run(run);
    ADD_FAILURE() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cam/0.png"), std::string::npos) << e.what();
  }
  fs::remove_all(tmp);
}

TEST(FeaturesImport, ImportsTheSampleR2D2Features) {
  LOCFORGE_SHARED_PATH_OR_SKIP(src, "data/kapture/virtual_gallery_tutorial/local_features/r2d2_500");
  const fs::path tmp = locforge::testing::MakeTempDir("features_import");
  runtime::Registry registry;
  ASSERT_TRUE(registry.LoadFile(LOCFORGE_FEATURES_PLUGIN_FILE));
  const auto* stage = registry.Find("features/import");
  runtime::StageInstance instance(*stage, runtime::CheckStageParams(*stage, {{"path", src.string()}}));
  runtime::RunOptions run;
  run.workspace = tmp;
  run.output_dir = tmp / "out";
  instance.Run(run);
  k::Kapture out(tmp / "out");
  const auto images = out.FeatureImages(k::FeatureKind::kDescriptors, "r2d2_500");
  EXPECT_EQ(images.size(), 16u);
  ASSERT_FALSE(images.empty());
  EXPECT_EQ(out.ReadKeypoints("r2d2_500", images[0]).rows, 500);
  EXPECT_EQ(out.GetFeatureSet(k::FeatureKind::kDescriptors, "r2d2_500").info.keypoints_type, "r2d2_500");
  fs::remove_all(tmp);
}

TEST(FeaturesSiftPlugin, Conforms) {
  const auto report = testkit::CheckPlugin(LOCFORGE_FEATURES_PLUGIN_FILE);
  EXPECT_TRUE(report.ok()) << report.ToString();
}

TEST(FeaturesSiftPlugin, RunsDeterministically) {
  const fs::path tmp = locforge::testing::MakeTempDir("sift_det");
  const fs::path dataset = MakeDataset(tmp / "data", 3);
  runtime::Registry registry;
  ASSERT_TRUE(testkit::CheckLoads(registry, LOCFORGE_FEATURES_PLUGIN_FILE).ok());
  testkit::DeterminismCase c;
  c.stage_id = "features/sift";
  c.params = {{"max_keypoints", "200"}};
  c.inputs = {{"images", "kapture.dataset", dataset}};
  c.threads = 2;
  const auto report = testkit::CheckDeterminism(registry, c);
  EXPECT_TRUE(report.ok()) << report.ToString();
  fs::remove_all(tmp);
}

}  // namespace
}  // namespace locforge::sift

// XFeat against the authors' extraction computed in PyTorch by the recipe
// script (export_xfeat.py reference, stored in testdata/) on a crop of a real
// photograph (Strecha fountain-P11, ../shared/data/localization), and the
// free-size export against the authors' own fixed-size ONNX.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

#include "alike.h"
#include "locforge/kapture/kapture.h"
#include "locforge/runtime/registry.h"
#include "locforge/testkit.h"
#include "learned_reference_testing.h"
#include "testing.h"
#include "xfeat.h"

namespace locforge::learned {
namespace {

namespace fs = std::filesystem;
using namespace ::locforge::learned::reference;  // learned_reference_testing.h

TEST(Xfeat, ReproducesTheAuthorsExtractionOnARealPhotograph) {
  LOCFORGE_SHARED_PATH_OR_SKIP(image, "data/localization/strecha_fountain-P11/mapping/sensors/records_data/0000.jpg");
  LOCFORGE_LEARNED_MODEL_OR_SKIP(model, "xfeat.onnx");
  const fs::path ref = LOCFORGE_XFEAT_TESTDATA;
  const auto meta = ReadMeta(ref / "xfeat.txt");
  const cv::Mat rgb = ReferenceImage(image, meta);
  ASSERT_EQ(rgb.cols, 1000);  // not a multiple of 32: the authors' resize to 992x672 runs
  XfeatOptions o;
  o.model = model.string();
  o.top_k = std::stoi(meta.at("top_k"));
  std::string why;
  ASSERT_TRUE(o.Check(&why)) << why;
  const auto start = std::chrono::steady_clock::now();
  const XfeatFeatures f = ExtractXfeat(rgb, o);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(f.network_width, 992);
  EXPECT_EQ(f.network_height, 672);

  const std::vector<float> ref_kpt = ReadRaw<float>(ref / "xfeat.kpt.f32");
  const std::vector<float> ref_desc = ReadHalf(ref / "xfeat.desc.f16");
  const size_t stored = ref_kpt.size() / 2;
  ASSERT_EQ(stored, static_cast<size_t>(std::stoi(meta.at("stored"))));
  ASSERT_EQ(ref_desc.size(), stored * 64);
  EXPECT_EQ(f.count(), std::stoi(meta.at("keypoints")));
  for (int i = 1; i < f.count(); ++i) ASSERT_LE(f.scores[i], f.scores[i - 1]);
  for (int i = 0; i < f.count(); ++i) ASSERT_GT(f.scores[i], 0.0f);

  // Each of our best (a margin below the stored count: ranks may swap at the
  // cut): the nearest reference keypoint, within 1 px; its descriptor's cosine.
  const ReferenceAgreement a =
      CompareWithReference(f.raw_keypoints, f.descriptors, 64, ref_kpt, ref_desc, static_cast<int>(stored) * 9 / 10);
  std::cout << "xfeat on fountain-P11 0000.jpg [" << meta.at("crop") << "]: " << f.count()
            << " keypoints, network " << f.network_seconds << " s, extraction " << seconds << " s; "
            << a.matched << " / " << a.checked << " of our best at a reference keypoint (<= 1 px, max "
            << a.max_distance << " px), " << a.cosine_ok << " with descriptor cosine >= 0.99 (worst "
            << a.worst_cosine << ")\n";
  EXPECT_GE(a.matched, a.checked * 99 / 100);
  EXPECT_GE(a.cosine_ok, a.checked * 99 / 100);

  // SDK coordinates: pixel centres of the 992x672 grid scaled to 1000x700.
  for (int i = 0; i < f.count(); ++i) {
    EXPECT_NEAR(f.keypoints[2 * i], f.raw_keypoints[2 * i] + 0.5f * 1000 / 992, 1e-3);
    EXPECT_NEAR(f.keypoints[2 * i + 1], f.raw_keypoints[2 * i + 1] + 0.5f * 700 / 672, 1e-3);
    if (HasFailure()) break;
  }
}

// The network of the recipe script, exported at a free size, against the
// authors' own fixed 640x640 export on the same input: same three outputs.
TEST(Xfeat, FreeSizeExportEqualsTheAuthorsFixedSizeOnnx) {
  LOCFORGE_SHARED_PATH_OR_SKIP(shipped, "models/xfeat/xfeat.onnx");
  LOCFORGE_LEARNED_MODEL_OR_SKIP(model, "xfeat.onnx");
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0, 1);
  const int grey_size[4] = {1, 1, 640, 640}, rgb_size[4] = {1, 3, 640, 640};
  cv::Mat grey(4, grey_size, CV_32F), rgb(4, rgb_size, CV_32F);
  const size_t plane = 640 * 640;
  for (size_t i = 0; i < plane; ++i) {
    // A smooth image with noise: the logits vary like on a photograph.
    const float v = 0.5f + 0.3f * std::sin(0.05f * (i % 640)) * std::cos(0.03f * (i / 640)) + 0.1f * u(rng);
    grey.ptr<float>()[i] = v;
    for (int c = 0; c < 3; ++c) rgb.ptr<float>()[c * plane + i] = v;  // mean over RGB = v
  }
  cv::dnn::Net ours = cv::dnn::readNetFromONNX(model.string());
  cv::dnn::Net theirs = cv::dnn::readNetFromONNX(shipped.string());
  ours.setInput(grey, "image");
  theirs.setInput(rgb, "input");
  std::vector<cv::Mat> a, b;
  ours.forward(a, std::vector<cv::String>{"descriptors", "keypoints", "reliability"});
  theirs.forward(b, std::vector<cv::String>{"output", "1266", "266"});
  ASSERT_EQ(a.size(), 3u);
  ASSERT_EQ(b.size(), 3u);
  const char* names[3] = {"descriptors", "keypoint logits", "reliability"};
  for (int i = 0; i < 3; ++i) {
    ASSERT_EQ(a[i].total(), b[i].total()) << names[i];
    const double diff = cv::norm(a[i].reshape(1, 1), b[i].reshape(1, 1), cv::NORM_INF);
    const double scale = cv::norm(b[i].reshape(1, 1), cv::NORM_INF);
    std::cout << names[i] << ": max |ours - authors'| = " << diff << " (max |authors'| " << scale << ")\n";
    EXPECT_LT(diff, 1e-4 * std::max(1.0, scale)) << names[i];
  }
}

TEST(Xfeat, AnySizeAndMaxSize) {
  LOCFORGE_LEARNED_MODEL_OR_SKIP(model, "xfeat.onnx");
  std::mt19937 rng(3);
  cv::Mat rgb(437, 611, CV_8UC3);
  cv::randu(rgb, 0, 255);
  cv::GaussianBlur(rgb, rgb, cv::Size(5, 5), 1.5);
  XfeatOptions o;
  o.model = model.string();
  const XfeatFeatures f = ExtractXfeat(rgb, o);
  EXPECT_EQ(f.network_width, 608);
  EXPECT_EQ(f.network_height, 416);
  ASSERT_GT(f.count(), 100);
  EXPECT_LE(f.count(), 4096);
  for (int i = 0; i < f.count(); ++i) {
    ASSERT_TRUE(f.keypoints[2 * i] > 0 && f.keypoints[2 * i] < 611 && f.keypoints[2 * i + 1] > 0 &&
                f.keypoints[2 * i + 1] < 437);
    double n = 0;
    for (int k = 0; k < 64; ++k) n += double(f.descriptors[64 * i + k]) * f.descriptors[64 * i + k];
    ASSERT_NEAR(n, 1.0, 1e-4);
  }
  o.max_size = 320;
  o.top_k = 200;
  const XfeatFeatures g = ExtractXfeat(rgb, o);
  EXPECT_EQ(g.network_width, 320);  // 611 * 320 / 611 = 320
  EXPECT_EQ(g.network_height, 224); // floor(437 * 320 / 611 = 228.9 / 32) * 32
  EXPECT_EQ(g.count(), 200);
  for (int i = 0; i < g.count(); ++i)
    ASSERT_TRUE(g.keypoints[2 * i] > 0 && g.keypoints[2 * i] < 611 && g.keypoints[2 * i + 1] > 0 &&
                g.keypoints[2 * i + 1] < 437);
  cv::Mat tiny(20, 40, CV_8UC3, cv::Scalar(0));
  EXPECT_THROW(ExtractXfeat(tiny, o), InputError);
}

// Both stages through the plugin on a real kapture (fountain-P11 mapping,
// six 1536x1024 photographs): kapture features of every image.
TEST(XfeatAlikeStages, WriteKaptureFeaturesOfEveryImage) {
  LOCFORGE_SHARED_PATH_OR_SKIP(mapping, "data/localization/strecha_fountain-P11/mapping");
  LOCFORGE_LEARNED_MODEL_OR_SKIP(xfeat, "xfeat.onnx");
  LOCFORGE_LEARNED_MODEL_OR_SKIP(alike, "alike-t.onnx");
  const fs::path tmp = locforge::testing::MakeTempDir("xfeat_alike_stages");
  runtime::Registry registry;
  ASSERT_TRUE(registry.LoadFile(LOCFORGE_FEATURES_PLUGIN_FILE));
  const runtime::InputArtifact images{"images", "kapture.dataset", mapping};
  testkit::RunStage(registry, "features/xfeat", {{"model", xfeat.string()}, {"top_k", "1000"}}, {images},
                    tmp / "xfeat");
  testkit::RunStage(registry, "features/alike", {{"model", alike.string()}, {"max_size", "512"}}, {images},
                    tmp / "alike");
  const kapture::Kapture source(mapping);
  const auto names = source.CameraImages();
  ASSERT_EQ(names.size(), 6u);
  for (const auto& [type, dim, folder] :
       {std::tuple<std::string, int, std::string>{"xfeat", 64, "xfeat"}, {"alike", 64, "alike"}}) {
    const kapture::Kapture out(tmp / folder);
    for (const auto& name : names) {
      const auto kp = out.ReadKeypoints(type, name);
      const auto de = out.ReadDescriptors(type, name);
      EXPECT_EQ(kp.dsize, 2) << type;
      EXPECT_EQ(de.dsize, dim) << type;
      EXPECT_EQ(kp.rows, de.rows) << type;
      EXPECT_GT(kp.rows, 300) << type << " " << name;
      if (type == "xfeat") EXPECT_EQ(kp.rows, 1000) << name;
      for (int64_t i = 0; i < kp.rows; ++i)
        ASSERT_TRUE(kp.At(i, 0) > 0 && kp.At(i, 0) < 1536 && kp.At(i, 1) > 0 && kp.At(i, 1) < 1024)
            << type << " " << name;
    }
  }
  fs::remove_all(tmp);
}

TEST(Xfeat, OptionsAndMissingModel) {
  XfeatOptions o;
  std::string why;
  EXPECT_FALSE(o.Check(&why));
  EXPECT_NE(why.find("model"), std::string::npos);
  o.model = "/nonexistent/xfeat.onnx";
  EXPECT_TRUE(o.Check(&why)) << why;
  o.max_size = 16;
  EXPECT_FALSE(o.Check(&why));
  EXPECT_NE(why.find("max_size"), std::string::npos);
  o.max_size = 0;
  o.type = "a/b";
  EXPECT_FALSE(o.Check(&why));
  o.type = "xfeat";
  try {
    ExtractXfeat(cv::Mat(64, 64, CV_8UC3, cv::Scalar(1, 2, 3)), o);
    FAIL() << "no error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/xfeat.onnx"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace locforge::learned

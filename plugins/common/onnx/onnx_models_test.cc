// The ONNX global descriptors (NetVLAD, AP-GeM, DELG) and D2-Net against
// numpy, with small architecture-faithful models that the test generates
// (testdata/onnx_models.py, python3-onnx + python3-numpy): the C++ plugin's
// output must equal the numpy forward pass / the numpy port of the authors'
// D2-Net extraction. Skips without python3-onnx, fails then under
// LOCFORGE_REQUIRE_SHARED=1.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <opencv2/core.hpp>
#include <random>
#include <sstream>

#include "d2net.h"
#include "global_descriptor.h"
#include "locforge/kapture/csv.h"
#include "locforge/kapture/kapture.h"
#include "locforge/runtime/registry.h"
#include "locforge/testkit.h"
#include "testing.h"

namespace locforge::learned {
namespace {

namespace k = locforge::kapture;

#define LOCFORGE_ONNX_PYTHON_OR_SKIP()                                                      \
  if (std::string(LOCFORGE_ONNX_PYTHON).empty()) {                                          \
    if (::locforge::testing::SharedRequired())                                               \
      FAIL() << "no python3 with onnx + numpy (python3-onnx, python3-numpy) and "           \
                "LOCFORGE_REQUIRE_SHARED=1";                                                 \
    GTEST_SKIP() << "no python3 with onnx + numpy: install python3-onnx and python3-numpy " \
                    "to generate the test models";                                           \
  }

std::string RunPython(const std::string& args) {
  const std::string command = std::string(LOCFORGE_ONNX_PYTHON) + " " +
                              LOCFORGE_LEARNED_MODELS_SCRIPT + " " + args;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) throw Error("cannot run " + command);
  std::string out;
  char buffer[256];
  while (fgets(buffer, sizeof buffer, pipe)) out += buffer;
  if (pclose(pipe) != 0) throw Error("failed: " + command + "\n" + out);
  return out;
}

void WriteRaw(const fs::path& file, const void* data, size_t bytes) {
  std::ofstream out(file, std::ios::binary);
  out.write(static_cast<const char*>(data), static_cast<std::streamsize>(bytes));
}

std::vector<float> ReadFloats(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  in.seekg(0, std::ios::end);
  std::vector<float> v(static_cast<size_t>(in.tellg()) / sizeof(float));
  in.seekg(0);
  in.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(float)));
  return v;
}

// A smooth pattern plus noise, 8-bit RGB.
cv::Mat TestImage(int h, int w, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, 40);
  cv::Mat rgb(h, w, CV_8UC3);
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j)
      for (int c = 0; c < 3; ++c)
        rgb.at<cv::Vec3b>(i, j)[c] = cv::saturate_cast<uint8_t>(
            127 + 60 * std::sin(0.1 * j + 0.08 * i + c) + noise(rng));
  return rgb;
}

class OnnxModels : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (std::string(LOCFORGE_ONNX_PYTHON).empty()) return;
    dir_ = locforge::testing::MakeTempDir("learned_onnx");
    RunPython("make " + dir_.string());
  }
  static void TearDownTestSuite() {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  // numpy forward of `model` on a 1x3xHxW blob.
  static std::vector<float> NumpyForward(const std::string& model, const cv::Mat& blob) {
    const fs::path in = dir_ / (model + ".in.f32"), out = dir_ / (model + ".out.f32");
    WriteRaw(in, blob.ptr<float>(), blob.total() * sizeof(float));
    RunPython("forward " + model + " " + dir_.string() + " " + in.string() + " 3 " +
        std::to_string(blob.size[2]) + " " + std::to_string(blob.size[3]) + " " + out.string());
    return ReadFloats(out);
  }
  static std::string Model(const std::string& name) { return (dir_ / (name + ".onnx")).string(); }
  static fs::path dir_;
};
fs::path OnnxModels::dir_;

double MaxAbsDiff(const std::vector<float>& a, const std::vector<float>& b) {
  EXPECT_EQ(a.size(), b.size());
  double m = 0;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) m = std::max(m, double(std::abs(a[i] - b[i])));
  return m;
}

double Norm(const std::vector<float>& v) {
  double n = 0;
  for (float x : v) n += double(x) * x;
  return std::sqrt(n);
}

// ------------------------------------------------------------ preprocessing

TEST(GlobalPreprocessing, ResizePoliciesChannelOrderAndNormalisation) {
  const cv::Mat rgb(60, 90, CV_8UC3, cv::Scalar(200, 100, 50));  // R, G, B
  GlobalOptions o = GlobalOptions::Defaults(GlobalModel::kApGem);
  o.max_side = 32;
  cv::Mat blob = GlobalInputBlob(rgb, o, 1.0);
  ASSERT_EQ(blob.dims, 4);
  EXPECT_EQ(blob.size[1], 3);
  EXPECT_EQ(blob.size[2], 21);  // 60 * 32 / 90 = 21.3
  EXPECT_EQ(blob.size[3], 32);
  // ImageNet normalisation of RGB pixels in [0, 255].
  EXPECT_NEAR(blob.ptr<float>(0, 0)[5], (200 - 123.675) / 58.395, 1e-5);
  EXPECT_NEAR(blob.ptr<float>(0, 1)[5], (100 - 116.28) / 57.12, 1e-5);
  EXPECT_NEAR(blob.ptr<float>(0, 2)[5], (50 - 103.53) / 57.375, 1e-5);
  // max_side never upscales; scales apply after it.
  o.max_side = 1024;
  blob = GlobalInputBlob(rgb, o, 0.5);
  EXPECT_EQ(blob.size[2], 30);
  EXPECT_EQ(blob.size[3], 45);
  // fixed: NetVLAD's default 640 x 480.
  const GlobalOptions n = GlobalOptions::Defaults(GlobalModel::kNetVlad);
  blob = GlobalInputBlob(rgb, n, 1.0);
  EXPECT_EQ(blob.size[2], 480);
  EXPECT_EQ(blob.size[3], 640);
  // DELG: (pixel - 128) / 128; BGR order puts blue first.
  GlobalOptions d = GlobalOptions::Defaults(GlobalModel::kDelg);
  d.channel_order = "BGR";
  blob = GlobalInputBlob(rgb, d, 1.0);
  EXPECT_EQ(blob.size[3], 90);
  EXPECT_NEAR(blob.ptr<float>(0, 0)[0], (50 - 128) / 128.0, 1e-6);
  EXPECT_NEAR(blob.ptr<float>(0, 2)[0], (200 - 128) / 128.0, 1e-6);
  ASSERT_EQ(d.scales.size(), 3u);
  std::string why;
  EXPECT_TRUE(d.Check(&why) || why.find("model") != std::string::npos) << why;
  d.model = "m.onnx";
  EXPECT_TRUE(d.Check(&why)) << why;
  d.std = {1, 0, 1};
  EXPECT_FALSE(d.Check(&why));
}

TEST(GlobalPostprocessing, PcaWhiteningFileIsReadAndApplied) {
  const fs::path tmp = locforge::testing::MakeTempDir("learned_pca");
  const int din = 5, dout = 3;
  std::vector<float> mean = {0.1f, -0.2f, 0.3f, 0.0f, 0.5f};
  std::vector<float> proj(dout * din);
  for (int i = 0; i < dout * din; ++i) proj[i] = std::sin(1.0f + i);
  std::string bytes("LFPCA1\0\0", 8);
  const int32_t dims[2] = {din, dout};
  bytes.append(reinterpret_cast<const char*>(dims), sizeof dims);
  bytes.append(reinterpret_cast<const char*>(mean.data()), mean.size() * 4);
  bytes.append(reinterpret_cast<const char*>(proj.data()), proj.size() * 4);
  WriteRaw(tmp / "pca.bin", bytes.data(), bytes.size());
  const PcaWhitening p = PcaWhitening::Read((tmp / "pca.bin").string());
  const std::vector<float> x = {1, 2, 3, 4, 5};
  std::vector<double> y(dout, 0.0);
  double n = 0;
  for (int r = 0; r < dout; ++r) {
    for (int i = 0; i < din; ++i) y[r] += double(proj[r * din + i]) * (x[i] - mean[i]);
    n += y[r] * y[r];
  }
  const std::vector<float> got = p.Apply(x);
  ASSERT_EQ(got.size(), 3u);
  for (int r = 0; r < dout; ++r) EXPECT_NEAR(got[r], y[r] / std::sqrt(n), 1e-6);
  EXPECT_EQ(PcaWhitening::Read((tmp / "pca.bin").string(), 2).Apply(x).size(), 2u);
  // Truncated and foreign files: InputError naming the file.
  WriteRaw(tmp / "short.bin", bytes.data(), bytes.size() - 4);
  WriteRaw(tmp / "bad.bin", "hello world, no pca", 19);
  for (const char* name : {"short.bin", "bad.bin"}) {
    try {
      PcaWhitening::Read((tmp / name).string());
      ADD_FAILURE() << name << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
  fs::remove_all(tmp);
}

// ------------------------------------------------------- generated models

TEST_F(OnnxModels, NetVladMatchesNumpy) {
  LOCFORGE_ONNX_PYTHON_OR_SKIP();
  const cv::Mat rgb = TestImage(75, 100, 1);
  GlobalOptions o = GlobalOptions::Defaults(GlobalModel::kNetVlad);
  o.model = Model("netvlad");
  o.width = 64;  // the test model's fixed input size
  o.height = 48;
  const cv::Mat blob = GlobalInputBlob(rgb, o, 1.0);
  ASSERT_EQ(blob.size[2], 48);
  const std::vector<float> expected = NumpyForward("netvlad", blob);
  ASSERT_EQ(expected.size(), 4u * 16u);  // K = 4 clusters x C = 16
  const GlobalDescriptor g = ExtractGlobal(rgb, o);
  EXPECT_EQ(g.raw.size(), 64u);
  EXPECT_LT(MaxAbsDiff(g.values, expected), 1e-4);
  EXPECT_NEAR(Norm(g.values), 1.0, 1e-5);
  // Intra-normalisation: each cluster's 16-D block has norm 1 / sqrt(K).
  for (int c = 0; c < 4; ++c) {
    double n = 0;
    for (int i = 0; i < 16; ++i) n += double(g.values[c * 16 + i]) * g.values[c * 16 + i];
    EXPECT_NEAR(std::sqrt(n), 0.5, 1e-4);
  }
}

TEST_F(OnnxModels, ApGemMatchesNumpyAndRanks) {
  LOCFORGE_ONNX_PYTHON_OR_SKIP();
  GlobalOptions o = GlobalOptions::Defaults(GlobalModel::kApGem);
  o.model = Model("gem");
  o.max_side = 40;
  const cv::Mat a = TestImage(60, 90, 2);
  const cv::Mat blob = GlobalInputBlob(a, o, 1.0);
  EXPECT_EQ(blob.size[2], 27);
  EXPECT_EQ(blob.size[3], 40);
  const std::vector<float> expected = NumpyForward("gem", blob);
  ASSERT_EQ(expected.size(), 6u);
  const GlobalDescriptor g = ExtractGlobal(a, o);
  EXPECT_LT(MaxAbsDiff(g.values, expected), 1e-4);
  // Ranking: a slightly brightened copy of `a` is closer to `a` than other
  // images are.
  cv::Mat brighter;
  a.convertTo(brighter, -1, 1.0, 6);
  auto cosine = [&](const cv::Mat& x, const cv::Mat& y) {
    const auto dx = ExtractGlobal(x, o).values, dy = ExtractGlobal(y, o).values;
    double s = 0;
    for (size_t i = 0; i < dx.size(); ++i) s += double(dx[i]) * dy[i];
    return s;
  };
  const double same = cosine(a, brighter);
  for (unsigned seed : {3u, 4u, 5u}) {
    cv::Mat other;  // another scene: another noise, the pattern inverted
    cv::bitwise_not(TestImage(60, 90, seed), other);
    EXPECT_GT(same, cosine(a, other)) << seed;
  }
}

TEST_F(OnnxModels, DelgMultiScaleSumsL2NormalisedScales) {
  LOCFORGE_ONNX_PYTHON_OR_SKIP();
  GlobalOptions o = GlobalOptions::Defaults(GlobalModel::kDelg);
  o.model = Model("gem");  // a GeM + whitening head stands for DELG's global head
  o.max_side = 48;
  const cv::Mat rgb = TestImage(64, 96, 6);
  std::vector<double> sum(6, 0.0);
  for (double s : o.scales) {
    const cv::Mat blob = GlobalInputBlob(rgb, o, s);
    EXPECT_EQ(blob.size[3], static_cast<int>(std::lround(48 * s)));
    const std::vector<float> d = NumpyForward("gem", blob);  // L2-normalised
    for (size_t i = 0; i < d.size(); ++i) sum[i] += d[i];
  }
  double n = 0;
  for (double x : sum) n += x * x;
  std::vector<float> expected(sum.size());
  for (size_t i = 0; i < sum.size(); ++i) expected[i] = static_cast<float>(sum[i] / std::sqrt(n));
  const GlobalDescriptor g = ExtractGlobal(rgb, o);
  EXPECT_EQ(g.input_sizes.size(), 6u);
  EXPECT_LT(MaxAbsDiff(g.values, expected), 1e-4);
}

// Keypoints of a against b: each of a at a keypoint of b (1e-3 px, same
// scale) with the same descriptor and score.
struct Agreement {
  int matched = 0;
  double max_descriptor_diff = 0, max_score_diff = 0;
};
Agreement Compare(const std::vector<float>& kpt_a, const std::vector<float>& desc_a,
                  const std::vector<float>& score_a, const std::vector<float>& kpt_b,
                  const std::vector<float>& desc_b, const std::vector<float>& score_b, int c) {
  Agreement r;
  const size_t na = score_a.size(), nb = score_b.size();
  for (size_t i = 0; i < na; ++i) {
    for (size_t j = 0; j < nb; ++j) {
      if (std::abs(kpt_a[3 * i] - kpt_b[3 * j]) > 1e-3f || std::abs(kpt_a[3 * i + 1] - kpt_b[3 * j + 1]) > 1e-3f ||
          std::abs(kpt_a[3 * i + 2] - kpt_b[3 * j + 2]) > 1e-5f)
        continue;
      ++r.matched;
      for (int k = 0; k < c; ++k)
        r.max_descriptor_diff = std::max(r.max_descriptor_diff, double(std::abs(desc_a[i * c + k] - desc_b[j * c + k])));
      r.max_score_diff = std::max(r.max_score_diff, double(std::abs(score_a[i] - score_b[j])));
      break;
    }
  }
  return r;
}

TEST_F(OnnxModels, D2netMatchesTheAuthorsExtractionPortedToNumpy) {
  LOCFORGE_ONNX_PYTHON_OR_SKIP();
  const cv::Mat rgb = TestImage(64, 80, 7);
  WriteRaw(dir_ / "d2.u8", rgb.data, rgb.total() * 3);
  for (const auto& [scales, score] :
       std::vector<std::pair<std::string, std::string>>{{"0.5,1,2", "authors"}, {"1", "authors"}, {"1", "soft"}}) {
    SCOPED_TRACE(scales + " " + score);
    const std::string prefix = (dir_ / ("d2_" + score + scales)).string();
    const int n = std::stoi(RunPython("d2net " + dir_.string() + " " + (dir_ / "d2.u8").string() + " 64 80 " +
                                scales + " " + score + " " + prefix));
    const std::vector<float> kpt = ReadFloats(prefix + ".kpt"), sc = ReadFloats(prefix + ".scores"),
                             desc = ReadFloats(prefix + ".desc");
    ASSERT_EQ(sc.size(), static_cast<size_t>(n));
    ASSERT_GT(n, 10);
    D2netOptions o;
    o.model = Model("d2net");
    o.scales.clear();
    std::stringstream ss(scales);
    for (std::string s; std::getline(ss, s, ',');) o.scales.push_back(std::stod(s));
    o.score = score;
    const D2netFeatures f = ExtractD2net(rgb, o);
    EXPECT_EQ(f.channels, 16);
    EXPECT_EQ(f.levels, static_cast<int>(o.scales.size()));
    EXPECT_EQ(f.count(), n);
    const Agreement a = Compare(kpt, desc, sc, f.raw_keypoints, f.descriptors, f.scores, 16);
    std::cout << scales << " " << score << ": numpy " << n << " keypoints, C++ " << f.count() << ", "
              << a.matched << " at the same place; max descriptor diff " << a.max_descriptor_diff
              << ", max score diff " << a.max_score_diff << "\n";
    EXPECT_GE(a.matched, 0.98 * n);
    EXPECT_LT(a.max_descriptor_diff, 1e-4);
    EXPECT_LT(a.max_score_diff, score == "soft" ? 1e-6 : 1e-4);
    for (int i = 0; i < f.count(); ++i) {
      EXPECT_NEAR(f.keypoints[3 * i], f.raw_keypoints[3 * i] + 0.5f, 1e-5);
      std::vector<float> d(f.descriptors.begin() + 16 * i, f.descriptors.begin() + 16 * (i + 1));
      EXPECT_NEAR(Norm(d), 1.0, 1e-5);
      if (HasFailure()) break;
    }
    // top_k: the best scores first.
    o.top_k = 10;
    const D2netFeatures top = ExtractD2net(rgb, o);
    ASSERT_EQ(top.count(), 10);
    std::vector<float> sorted = f.scores;
    std::sort(sorted.rbegin(), sorted.rend());
    for (int i = 0; i < 10; ++i) EXPECT_FLOAT_EQ(top.scores[i], sorted[i]);
  }
}

// ------------------------------------------------------- stages end to end

using testkit::RunStage;

TEST_F(OnnxModels, StagesWriteKaptureFeaturesOfEveryImage) {
  LOCFORGE_ONNX_PYTHON_OR_SKIP();
  LOCFORGE_SHARED_PATH_OR_SKIP(shared, "data/kapture/virtual_gallery_tutorial");
  const fs::path tmp = locforge::testing::MakeTempDir("learned_stages");
  runtime::Registry registry;
  for (const char* f : {LOCFORGE_FEATURES_PLUGIN_FILE, LOCFORGE_GLOBAL_PLUGIN_FILE})
    ASSERT_TRUE(registry.LoadFile(f));
  const runtime::InputArtifact map{"images", "kapture.dataset", shared / "mapping"};
  RunStage(registry, "global/apgem", {{"model", Model("gem")}, {"max_side", "96"}}, {map}, tmp / "apgem");
  RunStage(registry, "features/d2net", {{"model", Model("d2net")}, {"max_edge", "160"}, {"top_k", "50"}},
           {map}, tmp / "d2net");
  const k::Kapture images(shared / "mapping");
  const auto names = images.CameraImages();
  ASSERT_EQ(names.size(), 12u);
  const k::Kapture gf(tmp / "apgem"), lf(tmp / "d2net");
  for (const auto& name : names) {
    const auto g = gf.ReadGlobalFeatures("apgem", name);
    EXPECT_EQ(g.rows, 1);
    EXPECT_EQ(g.dsize, 6);
    const auto kp = lf.ReadKeypoints("d2net", name);
    const auto de = lf.ReadDescriptors("d2net", name);
    EXPECT_EQ(kp.dsize, 3);
    EXPECT_EQ(de.dsize, 16);
    EXPECT_EQ(kp.rows, de.rows);
    EXPECT_GT(kp.rows, 0);
    EXPECT_LE(kp.rows, 50);
    // keypoints in the 1920 x 1080 image (SDK convention)
    for (int64_t i = 0; i < kp.rows; ++i) {
      EXPECT_GE(kp.At(i, 0), 0);
      EXPECT_LE(kp.At(i, 0), 1920);
      EXPECT_LE(kp.At(i, 1), 1080);
    }
  }
  // pairs/retrieval consumes global/apgem's output: each query's top-1 is the
  // best cosine of our own descriptors.
  const std::string retrieval_plugin = LOCFORGE_PAIRS_PLUGIN_FILE;
  if (!retrieval_plugin.empty()) {
    ASSERT_TRUE(registry.LoadFile(retrieval_plugin));
    const runtime::InputArtifact query{"images", "kapture.dataset", shared / "query"};
    RunStage(registry, "global/apgem", {{"model", Model("gem")}, {"max_side", "96"}}, {query},
             tmp / "apgem_query");
    RunStage(registry, "pairs/retrieval", {{"topk", "1"}},
             {{"map_features", "kapture.global_features", tmp / "apgem"},
              {"query_features", "kapture.global_features", tmp / "apgem_query"},
              {"map", "kapture.dataset", shared / "mapping"},
              {"query", "kapture.dataset", shared / "query"}},
             tmp / "pairs");
    const k::Kapture qf(tmp / "apgem_query");
    std::map<std::string, std::string> top1;
    k::CsvReader reader(tmp / "pairs" / "pairs.txt");
    k::CsvRow row;
    while (reader.Next(&row)) top1[row.fields[0]] = row.fields[1];
    const auto queries = k::Kapture(shared / "query").CameraImages();
    ASSERT_EQ(top1.size(), queries.size());
    for (const auto& q : queries) {
      const auto dq = qf.ReadGlobalFeatures("apgem", q);
      std::string best;
      double best_score = -2;
      for (const auto& m : names) {
        const auto dm = gf.ReadGlobalFeatures("apgem", m);
        double dot = 0;
        for (int64_t i = 0; i < dq.dsize; ++i) dot += dq.At(0, i) * dm.At(0, i);
        if (dot > best_score) best_score = dot, best = m;
      }
      EXPECT_EQ(top1[q], best) << q;
    }
  }
  fs::remove_all(tmp);
}

TEST(LearnedPlugin, Conforms) {
  for (const char* f : {LOCFORGE_FEATURES_PLUGIN_FILE, LOCFORGE_GLOBAL_PLUGIN_FILE}) {
    const auto report = testkit::CheckPlugin(f);
    EXPECT_TRUE(report.ok()) << report.ToString();
  }
}

}  // namespace
}  // namespace locforge::learned

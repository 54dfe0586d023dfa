// localizer/posenet and localizer/esac: the pre/post-processing and the ESAC
// hypothesis split on known answers, then both stages end to end on small
// generated ONNX models (testdata_models.py) whose outputs are
// known: a PoseNet head checked against numpy, constant poses and scene
// coordinates of a known camera, and a gating network that picks the expert.
#include "scene_regression.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "locforge/kapture/kapture.h"
#include "locforge/runtime/registry.h"
#include "locforge/testkit.h"
#include "testing.h"

namespace locforge::regression {
namespace {

namespace lz = locforge::localization;

Camera TestCamera() { return Camera::FromModelName("PINHOLE", 640, 480, {500, 510, 321, 243}); }

Pose TestPose(double angle, const Eigen::Vector3d& centre) {
  const Eigen::Quaterniond world_from_camera(Eigen::AngleAxisd(angle, Eigen::Vector3d(0.2, 1, 0.1).normalized()));
  return Pose(world_from_camera, centre).Inverse();  // T_camera_world
}

// The scene coordinates (1x3xhxw) that a perfect expert would regress for a
// camera at `camera_from_world` seeing surfaces at depths 2-6 m.
cv::Mat ExactCoordinates(const Camera& camera, const Pose& camera_from_world, int h, int w, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> depth(2, 6);
  const int sizes[4] = {1, 3, h, w};
  cv::Mat out(4, sizes, CV_32F);
  const Pose world_from_camera = camera_from_world.Inverse();
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const Eigen::Vector2d pixel((j + 0.5) * camera.width / w, (i + 0.5) * camera.height / h);
      const Eigen::Vector3d p = world_from_camera * (camera.Unproject(pixel) * depth(rng));
      for (int c = 0; c < 3; ++c) out.ptr<float>(0, c)[i * w + j] = static_cast<float>(p[c]);
    }
  return out;
}

double PositionError(const Pose& a, const Pose& b) { return (a.Center() - b.Center()).norm(); }
double AngleError(const Pose& a, const Pose& b) { return a.q.angularDistance(b.q); }

TEST(SceneRegression, HypothesisBudgetFollowsTheGatingProbabilities) {
  EXPECT_EQ(HypothesisBudget({1.0}, 256), std::vector<int>({256}));
  EXPECT_EQ(HypothesisBudget({0.5, 0.25, 0.25}, 256), std::vector<int>({128, 64, 64}));
  // 0.6 * 10 = 6, 0.3 * 10 = 3, 0.1 * 10 = 1; remainders go to the largest.
  EXPECT_EQ(HypothesisBudget({0.6, 0.3, 0.1}, 10), std::vector<int>({6, 3, 1}));
  const std::vector<int> b = HypothesisBudget({0.45, 0.45, 0.1}, 7);
  EXPECT_EQ(b[0] + b[1] + b[2], 7);
  EXPECT_EQ(b, std::vector<int>({3, 3, 1}));
  // A confident gate leaves the others no hypotheses (they are not run).
  EXPECT_EQ(HypothesisBudget({0.999, 0.0005, 0.0005}, 256), std::vector<int>({256, 0, 0}));
  const std::vector<double> p = Softmax({0.f, std::log(3.f)});
  EXPECT_NEAR(p[0], 0.25, 1e-7);
  EXPECT_NEAR(p[1], 0.75, 1e-7);
  EXPECT_NEAR(Softmax({1000.f, 0.f})[0], 1.0, 1e-12);  // no overflow
}

TEST(SceneRegression, BestExpertHasMostInliersThenHighestProbability) {
  auto result = [](int expert, double p, bool ok, int inliers) {
    ExpertResult r;
    r.expert = expert;
    r.probability = p;
    r.pose.success = ok;
    r.pose.num_inliers = inliers;
    return r;
  };
  EXPECT_EQ(BestExpert({}), -1);
  EXPECT_EQ(BestExpert({result(0, 0.9, false, 0), result(1, 0.1, false, 3)}), -1);
  EXPECT_EQ(BestExpert({result(0, 0.9, true, 50), result(1, 0.1, true, 80)}), 1);  // evidence wins
  EXPECT_EQ(BestExpert({result(0, 0.2, true, 80), result(1, 0.8, true, 80)}), 1);  // tie: the gate
  EXPECT_EQ(BestExpert({result(0, 0.9, false, 99), result(1, 0.1, true, 12)}), 1);
}

TEST(SceneRegression, PoseFromRegressionInvertsCentreAndRotation) {
  const Pose truth = TestPose(0.7, {1, -2, 3});
  const Pose world_from_camera = truth.Inverse();
  const float c[3] = {float(world_from_camera.t.x()), float(world_from_camera.t.y()), float(world_from_camera.t.z())};
  // Any norm: the network's quaternion is scaled by 3.
  const float q[4] = {float(3 * world_from_camera.q.w()), float(3 * world_from_camera.q.x()),
                      float(3 * world_from_camera.q.y()), float(3 * world_from_camera.q.z())};
  Pose got;
  std::string why;
  ASSERT_TRUE(PoseFromRegression(c, q, &got, &why)) << why;
  EXPECT_LT(PositionError(got, truth), 1e-6);
  EXPECT_LT(AngleError(got, truth), 1e-6);
  const float zero[4] = {0, 0, 0, 0};
  EXPECT_FALSE(PoseFromRegression(c, zero, &got, &why));
  const float nan[3] = {std::nanf(""), 0, 0};
  EXPECT_FALSE(PoseFromRegression(nan, q, &got, &why));
  EXPECT_NE(why.find("non-finite"), std::string::npos);
}

TEST(SceneRegression, ExactSceneCoordinatesGiveTheCameraPose) {
  const Camera camera = TestCamera();
  const Pose truth = TestPose(-0.4, {0.5, 1.5, -2});
  cv::Mat coordinates = ExactCoordinates(camera, truth, 12, 16, 1);
  // A third of the cells wrong (an expert outside its region): outliers.
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> junk(-20, 20);
  for (int k = 0; k < 12 * 16; k += 3)
    for (int c = 0; c < 3; ++c) coordinates.ptr<float>(0, c)[k] = junk(rng);
  coordinates.ptr<float>(0, 0)[1] = std::nanf("");  // skipped
  const auto cs = SceneCoordinateCorrespondences(coordinates, camera);
  EXPECT_EQ(cs.size(), 12u * 16u - 1);
  lz::RansacOptions ransac;
  ransac.min_iterations = ransac.max_iterations = 64;
  lz::RigCamera rc;
  rc.focal = 505;
  const lz::AbsolutePoseResult r = lz::EstimateAbsolutePose(cs, {rc}, ransac);
  ASSERT_TRUE(r.success) << r.failure;
  EXPECT_EQ(r.num_inliers, 12 * 16 - 64 - 1);  // 64 junk cells, one NaN
  EXPECT_LT(PositionError(r.rig_from_world, truth), 1e-6);
  EXPECT_LT(AngleError(r.rig_from_world, truth), 1e-8);
}

TEST(SceneRegression, BlobResizesAndNormalisesRgb) {
  const cv::Mat rgb(48, 64, CV_8UC3, cv::Scalar(200, 100, 50));
  InputOptions o;
  o.width = 32;
  o.height = 16;
  std::string why;
  ASSERT_TRUE(o.Check(&why)) << why;
  const cv::Mat blob = learned::InputBlob(rgb, o);
  ASSERT_EQ(blob.dims, 4);
  EXPECT_EQ(blob.size[2], 16);
  EXPECT_EQ(blob.size[3], 32);
  EXPECT_NEAR(blob.ptr<float>(0, 0)[7], (200 - 123.675) / 58.395, 1e-5);
  EXPECT_NEAR(blob.ptr<float>(0, 2)[7], (50 - 103.53) / 57.375, 1e-5);
  o.std = {1, 0, 1};
  EXPECT_FALSE(o.Check(&why));
  o.std = {1, 1};
  EXPECT_FALSE(o.Check(&why));
}

// ------------------------------------------------------- generated models

class RegressionStages : public ::testing::Test {
 protected:
  void SetUp() override {
    if (std::string(LOCFORGE_ONNX_PYTHON).empty()) {
      if (locforge::testing::SharedRequired())
        FAIL() << "no python3 with onnx + numpy (python3-onnx, python3-numpy) and LOCFORGE_REQUIRE_SHARED=1";
      GTEST_SKIP() << "no python3 with onnx + numpy: install python3-onnx and python3-numpy";
    }
    dir_ = locforge::testing::MakeTempDir("regression_stages");
    ASSERT_TRUE(registry_.LoadFile(LOCFORGE_LOCALIZER_PLUGIN_FILE));
    // A query kapture: one 640x480 image of camera `cam`.
    query_ = dir_ / "query";
    fs::create_directories(query_ / "sensors/records_data");
    std::ofstream(query_ / "sensors/sensors.txt")
        << "# kapture format: 1.1\n# sensor_device_id, name, sensor_type, [sensor_params]+\n"
           "cam, , camera, PINHOLE, 640, 480, 500, 510, 321, 243\n";
    std::ofstream(query_ / "sensors/records_camera.txt")
        << "# kapture format: 1.1\n# timestamp, device_id, image_path\n7, cam, q/query.png\n";
    cv::Mat image(480, 640, CV_8UC3);
    cv::randu(image, 0, 255);
    fs::create_directories(query_ / "sensors/records_data/q");
    ASSERT_TRUE(cv::imwrite((query_ / "sensors/records_data/q/query.png").string(), image));
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  void Python(const std::string& args) {
    const std::string command = std::string(LOCFORGE_ONNX_PYTHON) + " " + LOCFORGE_REGRESSION_MODELS_SCRIPT + " " + args;
    ASSERT_EQ(std::system(command.c_str()), 0) << command;
  }
  void WriteExpert(const fs::path& file, const cv::Mat& coordinates) {
    const fs::path raw = dir_ / "coords.f32";
    std::ofstream(raw, std::ios::binary)
        .write(reinterpret_cast<const char*>(coordinates.ptr<float>()), std::streamsize(coordinates.total() * 4));
    Python("expert " + file.string() + " " + raw.string() + " " + std::to_string(coordinates.size[2]) + " " +
           std::to_string(coordinates.size[3]) + " 8");
  }
  // Runs `stage` on the query; the estimated pose of the image (or nullopt).
  std::optional<Pose> Run(const std::string& stage, const std::vector<std::pair<std::string, std::string>>& params,
                          const std::string& out) {
    testkit::RunStage(registry_, stage, params, {{"query", "kapture.dataset", query_}}, dir_ / out);
    return kapture::Kapture(dir_ / out).DevicePose(7, "cam");
  }
  fs::path dir_, query_;
  runtime::Registry registry_;
};

TEST_F(RegressionStages, PoseNetOutputsMatchNumpyAndConstantsComeBackExactly) {
  Python("posenet " + dir_.string() + " 3");
  const auto got = Run("localizer/posenet", {{"model", (dir_ / "posenet.onnx").string()}, {"width", "40"},
                                             {"height", "32"}}, "posenet");
  ASSERT_TRUE(got.has_value());
  // numpy on the same blob.
  InputOptions o;
  o.width = 40;
  o.height = 32;
  cv::Mat bgr = cv::imread((query_ / "sensors/records_data/q/query.png").string()), rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  const cv::Mat blob = learned::InputBlob(rgb, o);
  std::ofstream(dir_ / "in.f32", std::ios::binary)
      .write(reinterpret_cast<const char*>(blob.ptr<float>()), std::streamsize(blob.total() * 4));
  Python("posenet_forward " + dir_.string() + " " + (dir_ / "in.f32").string() + " 32 40 " + (dir_ / "out.f32").string());
  float v[7];
  std::ifstream(dir_ / "out.f32", std::ios::binary).read(reinterpret_cast<char*>(v), sizeof v);
  Pose expected;
  std::string why;
  ASSERT_TRUE(PoseFromRegression(v, v + 3, &expected, &why)) << why;
  EXPECT_LT(PositionError(*got, expected), 1e-4);
  EXPECT_LT(AngleError(*got, expected), 1e-5);
  // A network that says pose P: the trajectory holds P's inverse.
  const Pose truth = TestPose(1.1, {4, 5, -6});
  const Pose wc = truth.Inverse();
  char args[256];
  std::snprintf(args, sizeof args, "%.9g %.9g %.9g %.9g %.9g %.9g %.9g", wc.t.x(), wc.t.y(), wc.t.z(), wc.q.w(),
                wc.q.x(), wc.q.y(), wc.q.z());
  Python("constant_pose " + (dir_ / "constant.onnx").string() + " " + args);
  const auto constant = Run("localizer/posenet", {{"model", (dir_ / "constant.onnx").string()}}, "constant");
  ASSERT_TRUE(constant.has_value());
  EXPECT_LT(PositionError(*constant, truth), 1e-5);
  EXPECT_LT(AngleError(*constant, truth), 1e-6);
  // A zero quaternion: a failure with its reason, no pose.
  Python("constant_pose " + (dir_ / "zero.onnx").string() + " 1 2 3 0 0 0 0");
  EXPECT_FALSE(Run("localizer/posenet", {{"model", (dir_ / "zero.onnx").string()}}, "zero").has_value());
  EXPECT_NE(locforge::testing::ReadText(dir_ / "zero/failures.txt").find("quaternion ~ 0"), std::string::npos);
}

TEST_F(RegressionStages, EsacGatingPicksTheExpertAndItsSceneGivesThePose) {
  const Camera camera = TestCamera();
  const Pose a = TestPose(0.3, {1, 2, 3}), b = TestPose(-1.2, {-8, 0.5, 4});
  // Input 128x96 -> 16x12 cells (pool of 8).
  const fs::path two = dir_ / "two", one = dir_ / "one";
  fs::create_directories(two);
  fs::create_directories(one);
  WriteExpert(two / "expert_000.onnx", ExactCoordinates(camera, a, 12, 16, 1));
  WriteExpert(two / "expert_001.onnx", ExactCoordinates(camera, b, 12, 16, 2));
  fs::copy_file(two / "expert_001.onnx", one / "expert_000.onnx");
  const std::vector<std::pair<std::string, std::string>> size = {{"width", "128"}, {"height", "96"}};
  auto params = [&](const fs::path& models) {
    auto p = size;
    p.push_back({"model_dir", models.string()});
    return p;
  };
  Python("gating " + (two / "gating.onnx").string() + " 3 -1");  // p = 0.982, 0.018
  auto got = Run("localizer/esac", params(two), "esac_a");
  ASSERT_TRUE(got.has_value());
  EXPECT_LT(PositionError(*got, a), 1e-5);
  EXPECT_LT(AngleError(*got, a), 1e-6);
  // stats: the chosen expert and its probability.
  const auto stats = locforge::testing::ReadCsv(dir_ / "esac_a/localization_stats.csv");
  ASSERT_EQ(stats.size(), 2u);
  EXPECT_EQ(stats[1][2], "0");
  EXPECT_NEAR(std::stod(stats[1][3]), 1 / (1 + std::exp(-4.0)), 1e-6);
  // The gate rewritten at the same path (a retrained model): reloaded, not served stale.
  Python("gating " + (two / "gating.onnx").string() + " -2 2");
  got = Run("localizer/esac", params(two), "esac_b");
  ASSERT_TRUE(got.has_value());
  EXPECT_LT(PositionError(*got, b), 1e-5);
  // One expert, no gating network.
  got = Run("localizer/esac", params(one), "esac_one");
  ASSERT_TRUE(got.has_value()) << locforge::testing::ReadText(dir_ / "esac_one/localization_stats.csv");
  EXPECT_LT(PositionError(*got, b), 1e-5);
  // An expert whose coordinates are all one point: no pose, the reason listed.
  const int sizes[4] = {1, 3, 12, 16};
  WriteExpert(one / "expert_000.onnx", cv::Mat(4, sizes, CV_32F, cv::Scalar(1.5f)));
  EXPECT_FALSE(Run("localizer/esac", params(one), "esac_bad").has_value());
  EXPECT_NE(locforge::testing::ReadText(dir_ / "esac_bad/failures.txt").find("q/query.png"), std::string::npos);
  // Bad model folders are refused with the reason.
  auto refused = [&](std::vector<std::pair<std::string, std::string>> p, const std::string& what) {
    try {
      testkit::RunStage(registry_, "localizer/esac", p, {{"query", "kapture.dataset", query_}}, dir_ / "refused");
      ADD_FAILURE() << "accepted: " << what;
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  auto p = params(two);
  p.push_back({"experts", "10"});
  refused(p, "10 experts expected, 2 found");
  fs::remove(two / "gating.onnx");
  refused(params(two), "no gating.onnx");
  refused(params(dir_ / "query"), "no expert_000.onnx");
}

}  // namespace
}  // namespace locforge::regression

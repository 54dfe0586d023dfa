#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "dataset.h"
#include "kapture_out.h"
#include "locforge/error.h"
#include "locforge/kapture/kapture.h"
#include "testing.h"

namespace locforge::sim {
namespace {

std::vector<std::vector<std::string>> ReadRows(const fs::path& file) {
  std::ifstream in(file);
  EXPECT_TRUE(in.good()) << file;
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> fields;
    std::stringstream ss(line);
    std::string f;
    while (std::getline(ss, f, ',')) {
      const size_t a = f.find_first_not_of(' '), b = f.find_last_not_of(' ');
      fields.push_back(a == std::string::npos ? "" : f.substr(a, b - a + 1));
    }
    rows.push_back(fields);
  }
  return rows;
}

Pose PoseOf(const std::vector<std::string>& r, size_t first) {
  return Pose(Eigen::Quaterniond(std::stod(r[first]), std::stod(r[first + 1]), std::stod(r[first + 2]), std::stod(r[first + 3])),
              Eigen::Vector3d(std::stod(r[first + 4]), std::stod(r[first + 5]), std::stod(r[first + 6])));
}

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

class TinyDataset : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(locforge::testing::MakeTempDir("sim_tiny"));
    summary_ = new DatasetSummary(GenerateDataset(PresetOptions("tiny"), *dir_, 2));
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
    delete summary_;
  }
  static fs::path* dir_;
  static DatasetSummary* summary_;
};
fs::path* TinyDataset::dir_ = nullptr;
DatasetSummary* TinyDataset::summary_ = nullptr;

TEST_F(TinyDataset, WritesThreeKapturesWithEveryRecordFile) {
  ASSERT_EQ(summary_->sequences.size(), 3u);
  for (const char* split : {"mapping", "validation", "test"}) {
    const fs::path s = *dir_ / (std::string(split) == "mapping" ? "" : split) / "sensors";
    const auto sensors = ReadRows(s / "sensors.txt");
    ASSERT_EQ(sensors.size(), 13u) << split;  // 10 cameras, 2 lidars, wheels
    EXPECT_EQ(sensors[0][2], "camera");
    EXPECT_EQ(sensors[0][3], "PINHOLE");
    EXPECT_EQ(ReadRows(s / "rigs.txt").size(), 13u);
    const auto cams = ReadRows(s / "records_camera.txt");
    ASSERT_GT(cams.size(), 30u);
    for (size_t i = 0; i < cams.size(); i += 7) {
      const cv::Mat img = cv::imread((s / "records_data" / cams[i][2]).string());
      ASSERT_FALSE(img.empty()) << cams[i][2];
      EXPECT_EQ(img.cols, cams[i][1].rfind("ind", 0) == 0 ? 162 : 135);
      EXPECT_TRUE(fs::exists(*dir_ / "truth" / "masks" / split / (cams[i][2].substr(0, cams[i][2].size() - 3) + "png")));
    }
    const auto lidar = ReadRows(s / "records_lidar.txt");
    ASSERT_GT(lidar.size(), 10u);
    const LidarScan scan = DecodePcd(Slurp(s / "records_data" / lidar[0][2]), lidar[0][2]);
    EXPECT_GT(scan.points.size(), 3000u);
    EXPECT_GT(ReadRows(s / "records_wheel_encoder.txt").size(), 300u);
  }
  EXPECT_TRUE(fs::exists(*dir_ / "truth" / "calibration.yaml"));
  EXPECT_EQ(ReadRows(*dir_ / "truth" / "sequences.txt").size(), 3u);
}

TEST_F(TinyDataset, CameraPosesComposeFromRigPosesAndExtrinsics) {
  const fs::path s = *dir_ / "sensors";
  std::map<std::string, Pose> cam_from_rig;
  for (const auto& r : ReadRows(s / "rigs.txt")) cam_from_rig[r[1]] = PoseOf(r, 2);
  std::map<long long, Pose> rig_poses;
  std::vector<std::pair<long long, std::pair<std::string, Pose>>> cam_poses;
  for (const auto& r : ReadRows(s / "trajectories.txt")) {
    if (r[1] == "rig") rig_poses[std::stoll(r[0])] = PoseOf(r, 2);
    else cam_poses.push_back({std::stoll(r[0]), {r[1], PoseOf(r, 2)}});
  }
  ASSERT_GT(cam_poses.size(), 30u);
  double worst = 0;
  for (const auto& [ts, cp] : cam_poses) {
    auto it = rig_poses.lower_bound(ts);
    if (it == rig_poses.end()) --it;
    // T_cam_world = T_cam_rig * T_rig_world; the rig pose is up to 50 ms + clock offset away.
    const Pose composed = cam_from_rig.at(cp.first) * it->second;
    worst = std::max(worst, (composed.Center() - cp.second.Center()).norm());
  }
  EXPECT_LT(worst, 0.15);
  EXPECT_GT(worst, 0.0);
}

TEST_F(TinyDataset, QueriesStayInTheirAreas) {
  // Validation runs west of a split line, test east of it (0.3 m lateral
  // offset from the mapped line at most).
  double validation_max_x = -1e18, test_min_x = 1e18;
  for (const auto& r : ReadRows(*dir_ / "validation" / "sensors" / "trajectories.txt"))
    if (r[1] == "rig") validation_max_x = std::max(validation_max_x, PoseOf(r, 2).Center().x());
  for (const auto& r : ReadRows(*dir_ / "test" / "sensors" / "trajectories.txt"))
    if (r[1] == "rig") test_min_x = std::min(test_min_x, PoseOf(r, 2).Center().x());
  EXPECT_LT(validation_max_x, test_min_x + 0.9);
}

// Queries revisit the mapped space (else no method could localize them):
// their rig positions lie near a mapping rig position.
TEST_F(TinyDataset, QueriesRevisitTheMappedSpace) {
  std::vector<Eigen::Vector3d> mapped;
  for (const auto& r : ReadRows(*dir_ / "sensors" / "trajectories.txt"))
    if (r[1] == "rig") mapped.push_back(PoseOf(r, 2).Center());
  ASSERT_FALSE(mapped.empty());
  for (const char* split : {"validation", "test"}) {
    std::vector<double> distances;
    for (const auto& r : ReadRows(*dir_ / split / "sensors" / "trajectories.txt")) {
      if (r[1] != "rig") continue;
      double best = 1e18;
      for (const auto& m : mapped) best = std::min(best, (m - PoseOf(r, 2).Center()).head<2>().norm());
      distances.push_back(best);
    }
    ASSERT_GT(distances.size(), 10u) << split;
    std::sort(distances.begin(), distances.end());
    std::printf("%s: query-to-map distance median %.2f m, max %.2f m\n", split,
                distances[distances.size() / 2], distances.back());
    EXPECT_LT(distances[distances.size() / 2], 0.6) << split;
    EXPECT_LT(distances.back(), 1.5) << split;
  }
}

// The SDK's kapture reader accepts every kapture written, with no problem.
TEST_F(TinyDataset, SdkKaptureReaderFindsNoProblem) {
  for (const char* split : {"", "validation", "test"}) {
    const kapture::KaptureSummary k = kapture::InspectKapture(*dir_ / split);
    EXPECT_TRUE(k.problems.empty()) << split << ": " << kapture::FormatSummary(k);
    EXPECT_EQ(k.sensors_by_type.at("camera"), 10);
    EXPECT_EQ(k.sensors_by_type.at("lidar"), 2);
    EXPECT_EQ(k.sensors_by_type.at("wheel_encoder"), 1);
    EXPECT_EQ(k.rig_sensor_entries, 13);
    for (const auto& r : k.records) EXPECT_EQ(r.missing_files, 0) << r.sensor_type;
    // A camera's pose read through the SDK equals the one composed from the rig.
    kapture::Kapture kap(*dir_ / split);
    const auto* cam = kap.sensors().Find("ind_2");
    ASSERT_NE(cam, nullptr);
    ASSERT_TRUE(cam->camera.has_value());
    EXPECT_EQ(cam->camera->width, 162);
  }
}

TEST(Dataset, DeterministicWhateverTheThreads) {
  SimOptions o = PresetOptions("tiny");
  o.mapping_duration_s = 3;
  o.validation_sequences = o.test_sequences = 0;
  o.seed = 9;
  const fs::path a = locforge::testing::MakeTempDir("sim_det_a"), b = locforge::testing::MakeTempDir("sim_det_b");
  GenerateDataset(o, a, 1);
  GenerateDataset(o, b, 2);
  for (const char* f : {"sensors.txt", "rigs.txt", "trajectories.txt", "records_camera.txt", "records_lidar.txt",
                        "records_wheel_encoder.txt"})
    EXPECT_EQ(Slurp(a / "sensors" / f), Slurp(b / "sensors" / f)) << f;
  const auto cams = ReadRows(a / "sensors/records_camera.txt");
  for (size_t i = 0; i < cams.size(); i += 5)
    EXPECT_EQ(Slurp(a / "sensors/records_data" / cams[i][2]), Slurp(b / "sensors/records_data" / cams[i][2]));
  // Another seed gives another recording.
  o.seed = 10;
  const fs::path c = locforge::testing::MakeTempDir("sim_det_c");
  GenerateDataset(o, c, 2);
  EXPECT_NE(Slurp(a / "sensors/trajectories.txt"), Slurp(c / "sensors/trajectories.txt"));
  for (const auto& d : {a, b, c}) fs::remove_all(d);
}

TEST(Dataset, RefusesBadOptions) {
  SimOptions o = PresetOptions("tiny");
  o.crowdedness = -1;
  EXPECT_THROW(GenerateDataset(o, "/nonexistent", 1), ParamError);
  EXPECT_THROW(PresetOptions("huge"), ParamError);
  o = PresetOptions("tiny");
  o.scene_file = "/nonexistent/floor.yaml";
  EXPECT_THROW(GenerateDataset(o, locforge::testing::MakeTempDir("sim_bad"), 1), InputError);
}

TEST(KaptureOut, PcdRoundTrips) {
  LidarScan scan;
  scan.points.push_back({Eigen::Vector3f(1, 2, 3), 40, 7, 0.0123});
  scan.points.push_back({Eigen::Vector3f(-1, 0.5, 9), 200, 15, 0.0999});
  const LidarScan back = DecodePcd(EncodePcd(scan), "x.pcd");
  ASSERT_EQ(back.points.size(), 2u);
  EXPECT_EQ(back.points[1].xyz, scan.points[1].xyz);
  EXPECT_EQ(back.points[1].ring, 15);
  EXPECT_EQ(back.points[0].time, 0.0123);
  std::string broken = EncodePcd(scan);
  broken.pop_back();
  EXPECT_THROW(DecodePcd(broken, "x.pcd"), InputError);
  EXPECT_EQ(FormatNumber(0.1), "0.1");
  EXPECT_EQ(FormatNumber(2), "2.0");
}

}  // namespace
}  // namespace locforge::sim

// End to end through the host: the simulator's `tiny` recording ->
// configs/gt/full.yaml (LiDAR half, SIFT, pose-proximity pairs, mutual NN,
// two-view verification, spline bundle adjustment loop) started from a
// calibration perturbed away from the truth (3 % focal, 1.5 deg rotation),
// + eval/calibration of the starting and the refined poses/calibration
// against the simulator's truth. Measured numbers: docs/results/ground-truth.md.
#include <gtest/gtest.h>

#include <cstdlib>
#include <sstream>

#include "testing.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"

namespace locforge::sfm_gt {
namespace {

using testing::ReadCsv;

std::map<std::string, double> Row(const std::vector<std::vector<std::string>>& csv, const std::string& first) {
  std::map<std::string, double> out;
  for (size_t r = 1; r < csv.size(); ++r)
    if (!csv[r].empty() && csv[r][0] == first)
      for (size_t c = 1; c < csv[r].size() && c < csv[0].size(); ++c)
        out[csv[0][c]] = std::atof(csv[r][c].c_str());
  EXPECT_FALSE(out.empty()) << "no row " << first;
  return out;
}

TEST(SfmGtPipeline, TinyRecordingRefinedFromPerturbedCalibration) {
  const fs::path bin = LOCFORGE_BINARY_DIR;
  const fs::path src = LOCFORGE_SOURCE_DIR;
  const fs::path dir = testing::MakeTempDir("sfm_gt_pipeline");
  const fs::path dataset =
      testing::SimulateRecording(bin, dir, "{preset: tiny, seed: 0, masks: false, scale: 0.125}");
  ASSERT_FALSE(dataset.empty()) << ReadFile(dir / "sim.log");
  // configs/gt/full.yaml + the evaluation against the simulator's truth.
  std::string graph = ReadFile(src / "configs/gt/full.yaml");
  graph += R"(  eval:
    stage: eval/calibration
    inputs: {estimates: [start, gt.trajectories]}
    params: {reference: "${dataset}"}
)";
  WriteFileAtomic(dir / "full.yaml", graph);
  ASSERT_EQ(testing::RunHost(bin, {"run", (dir / "full.yaml").string(), "--workspace", (dir / "ws").string(),
                                   "--set", "dataset=" + dataset.string(), "--set", "focal_percent=3",
                                   "--set", "rotation_deg=1.5", "--set", "max_keypoints=1000", "--set",
                                   "pair_topk=8", "--set", "gt.rounds=3", "--set",
                                   "gt.filter_max_reproj_error=[8,4,2]"},
                              dir / "full.log"),
            0)
      << ReadFile(dir / "full.log");
  const fs::path gt = dir / "ws/nodes/gt";
  for (const char* f : {"sensors/sensors.txt", "sensors/rigs.txt", "sensors/trajectories.txt",
                        "sensors/records_camera.txt", "reconstruction/points3d.txt",
                        "reconstruction/observations.txt", "model/images.bin", "table4.md", "table4.csv",
                        "rounds.md", "rounds.csv", "spline_ba.json"})
    EXPECT_TRUE(fs::exists(gt / f)) << f;
  const auto table4 = ReadCsv(gt / "table4.csv");
  ASSERT_EQ(table4.size(), 2u);
  const double images = std::atof(table4[1][0].c_str());
  const double points = std::atof(table4[1][1].c_str());
  const double reproj = std::atof(table4[1][3].c_str());
  const auto eval = ReadCsv(dir / "ws/nodes/eval/calibration.csv");
  const auto start = Row(eval, "start"), refined = Row(eval, "gt");
  std::cout << ReadFile(gt / "rounds.md") << "\n" << ReadFile(dir / "ws/nodes/eval/calibration.md") << "\n";
  EXPECT_GT(images, 50);
  EXPECT_GT(points, 500);
  EXPECT_LT(reproj, 1.0);
  // Refined poses closer to the truth than the LiDAR poses (with the
  // perturbed extrinsics), focal lengths and camera rotations recovered
  // (measured figures: docs/results/ground-truth.md).
  EXPECT_LT(refined.at("position RMS (cm)"), 0.6 * start.at("position RMS (cm)"));
  EXPECT_LT(refined.at("rotation RMS (deg)"), 0.2 * start.at("rotation RMS (deg)"));
  EXPECT_NEAR(start.at("focal error RMS (%)"), 3.0, 1e-6);
  EXPECT_LT(refined.at("focal error RMS (%)"), 0.5);
  EXPECT_LT(refined.at("camera rotation RMS (deg)"), 0.25 * start.at("camera rotation RMS (deg)"));
  fs::remove_all(dir);
}

// configs/gt/lidar_depth.yaml on `tiny`: the LiDAR map projected into every
// mapping image, against the simulator's exact depth (measured on seed 0:
// coverage 79 %, median 1.25 cm, 85 % within 5 cm; `small`: docs/results/ground-truth.md).
TEST(LidarDepthPipeline, TinyRecordingAgainstExactDepth) {
  const fs::path bin = LOCFORGE_BINARY_DIR;
  const fs::path src = LOCFORGE_SOURCE_DIR;
  const fs::path dir = testing::MakeTempDir("lidar_depth_pipeline");
  ASSERT_EQ(testing::RunHost(bin, {"run", (src / "configs/gt/lidar_depth.yaml").string(), "--workspace",
                                   (dir / "ws").string(), "--set", "preset=tiny"},
                              dir / "run.log"),
            0)
      << ReadFile(dir / "run.log");
  const fs::path depth = dir / "ws/nodes/depth";
  const kapture::Kapture depth_kapture(depth);
  const auto records = depth_kapture.ReadDataRecords(kapture::kSensorDepth);
  EXPECT_EQ(records.size(), 152u);  // every mapping image of tiny
  for (const auto& r : records) EXPECT_TRUE(fs::exists(depth_kapture.RecordDataPath(r.path))) << r.path;
  const auto csv = ReadCsv(dir / "ws/nodes/depth_eval/depth.csv");
  ASSERT_GE(csv.size(), 2u);
  std::map<std::string, size_t> column;
  for (size_t c = 0; c < csv[0].size(); ++c) column[csv[0][c]] = c;
  bool checked = false;
  for (size_t r = 1; r < csv.size(); ++r) {
    if (csv[r][0] != "all") continue;
    const double coverage = std::atof(csv[r][column.at("coverage_percent")].c_str());
    const double median = std::atof(csv[r][column.at("median_m")].c_str());
    const double within = std::atof(csv[r][column.at("within_0.05m_percent")].c_str());
    std::cout << csv[r][1] << ": coverage " << coverage << " %, median " << median << " m, within 5 cm " << within
              << " %\n";
    EXPECT_GT(coverage, 70);
    EXPECT_LT(median, 0.025);
    EXPECT_GT(within, 78);
    checked = true;
  }
  EXPECT_TRUE(checked);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace locforge::sfm_gt

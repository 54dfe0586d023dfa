// End to end through the host: the simulator's `tiny` recording (default
// noise) -> lidar/preprocess -> slam/pose_graph (registration/gicp) ->
// eval/trajectory against the true platform trajectory, aligned only by the
// fixed first pose. Measured: 1.4 cm RMS ATE, 0.10 deg, 14 s (plugins/lidar/README.md).
#include <gtest/gtest.h>

#include <cstdlib>
#include <regex>

#include "../../tests/testing/testing.h"
#include "locforge/fs.h"

namespace locforge::lidar {
namespace {

double JsonNumber(const std::string& json, const std::string& object, const std::string& key) {
  const size_t at = json.find("\"" + object + "\"");
  EXPECT_NE(at, std::string::npos) << object;
  std::smatch m;
  const std::string rest = json.substr(at);
  EXPECT_TRUE(std::regex_search(rest, m, std::regex("\"" + key + "\": ([-0-9.eE+]+)"))) << key;
  return std::stod(m[1]);
}

TEST(LidarPipeline, TinySimulatorTrajectoryWithinCentimetres) {
  const fs::path bin = LOCFORGE_BINARY_DIR;
  const fs::path dir = testing::MakeTempDir("lidar_pipeline");
  // Two runs: the recording first (its folder is then the dataset of the rest).
  const std::string env = "LOCFORGE_PLUGIN_PATH='" + (bin / "lib/locforge/plugins").string() + "' ";
  const std::string host = (bin / "bin/locforge").string();
  WriteFileAtomic(dir / "sim.yaml", R"(locforge: 1
nodes:
  recording:
    stage: source/simulator
    params: {preset: tiny, seed: 0, masks: false, scale: 0.03}
)");
  ASSERT_EQ(std::system((env + host + " run '" + (dir / "sim.yaml").string() + "' --workspace '" +
                         (dir / "ws").string() + "' > '" + (dir / "sim.log").string() + "' 2>&1").c_str()),
            0)
      << ReadFile(dir / "sim.log");
  const fs::path dataset = fs::canonical(dir / "ws/nodes/recording");
  const std::string pipeline = R"(locforge: 1
vars:
  dataset: ""
nodes:
  scans:
    stage: lidar/preprocess
    params: {dataset: "${dataset}"}
  slam:
    stage: slam/pose_graph
    inputs: {scans: scans.scans}
    params: {dataset: "${dataset}"}
  eval:
    stage: eval/trajectory
    inputs: {estimate: slam.trajectories}
    params: {reference: "${dataset}", alignment: first}
)";
  WriteFileAtomic(dir / "gt.yaml", pipeline);
  ASSERT_EQ(std::system((env + host + " run '" + (dir / "gt.yaml").string() + "' --workspace '" +
                         (dir / "ws").string() + "' --set dataset='" + dataset.string() + "' > '" +
                         (dir / "gt.log").string() + "' 2>&1").c_str()),
            0)
      << ReadFile(dir / "gt.log");
  const std::string metrics = ReadFile(dir / "ws/nodes/eval/metrics.json");
  const double ate = JsonNumber(metrics, "ape_translation_m", "rmse");
  const double rot = JsonNumber(metrics, "ape_rotation_deg", "rmse");
  std::cout << "tiny: ATE " << ate << " m, " << rot << " deg\n";
  EXPECT_LT(ate, 0.04);  // measured 0.014
  EXPECT_LT(rot, 0.3);   // measured 0.10
  // Outputs of the SLAM stage.
  for (const char* f : {"sensors/trajectories.txt", "map.pcd", "map.ply", "pose_graph.g2o", "trajectories.svg", "slam.json"})
    EXPECT_TRUE(fs::exists(dir / "ws/nodes/slam" / f)) << f;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace locforge::lidar

// What slam/pose_graph writes (plugins/slam/README.md): trajectories of the
// rig and the cameras, the map, the graph, the top-down figure, joins.csv and
// slam.json.
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_OUTPUT_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_OUTPUT_H_

#include <chrono>
#include <string>
#include <vector>

#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "slam.h"

namespace locforge::lidar {

// The joins table: a line per sequence, then the attempts (CSV, # comments).
std::string JoinsCsv(const Slam& slam);

// Writes every output into `out`. `dataset`: the recording (sensors, rigs,
// camera records); scans: the scan records the keyframes came from.
// `start`: when the stage started (slam.json's times). Returns the one-line
// summary for the log.
std::string WriteSlamOutputs(const Slam& slam, const SlamOptions& options,
                             const std::vector<kapture::DataRecord>& scans, const kapture::Kapture& dataset,
                             const fs::path& out, std::chrono::steady_clock::time_point start);

// The error of a run whose parts could not all be joined (unjoined: error),
// or whose joins do not hold after optimisation: the table, and what to do.
std::string UnjoinedMessage(const Slam& slam);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_OUTPUT_H_

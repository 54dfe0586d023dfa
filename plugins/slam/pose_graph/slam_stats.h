// What the SLAM (slam.h) counts and times; a sequence's part (slam_part.h)
// carries the counts of its own steps.
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_STATS_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_STATS_H_

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "pose_graph.h"

namespace locforge::lidar {

// Wall time of each step (s), in the order they ran.
using StepTimes = std::vector<std::pair<std::string, double>>;

struct SlamStats {
  int sequential_fallbacks = 0, information_fallbacks = 0;
  int refinements = 0, refinements_rejected = 0;
  int64_t loop_tests = 0;
  int joins = 0, join_attempts = 0, join_tests = 0, join_rejected_loops = 0;
  int join_trials = 0;  // frames joined on trial (join.h)
  // Per sequence: the factor its odometry turns were scaled by (1: not
  // calibrated, too little turning or an implausible factor).
  std::map<std::string, double> odometry_yaw_scale;
  int sequential_reregistered = 0;  // registrations redone on re-undistorted keyframes
  PoseGraphSummary summary;
  StepTimes steps;  // keyframes, sequential edges, loops, joins, optimisation, join check
};

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_STATS_H_

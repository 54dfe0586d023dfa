// Top-down plot of pose-graph trajectories with their loop-closure edges,
// before and after optimisation (the paper's Figure 4), through the SDK's
// plot API (locforge/plot.h): one figure, written as SVG and PNG.
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_PLOT_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_PLOT_H_

#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "locforge/fs.h"
#include "locforge/plot.h"

namespace locforge::lidar {

struct PlotSequence {
  std::string name;
  std::vector<int> ids;               // node ids, in order
  std::vector<Eigen::Vector2d> xy;    // positions of those nodes
};

// One colour per sequence: before optimisation dashed and lighter, after
// solid; loop edges (pairs of node ids) as thin grey segments between the
// optimised nodes; a legend names the sequences and the two styles.
plot::Figure TopDownFigure(const std::vector<PlotSequence>& before, const std::vector<PlotSequence>& after,
                           const std::vector<std::pair<int, int>>& loops);
// Writes `stem`.svg and `stem`.png (atomic).
void WriteTopDown(const fs::path& stem, const std::vector<PlotSequence>& before,
                  const std::vector<PlotSequence>& after, const std::vector<std::pair<int, int>>& loops);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_PLOT_H_

// Top-down plot of pose-graph trajectories with their loop-closure edges,
// before and after optimisation side by side (the paper's Figure 4), as SVG.
#ifndef LOCFORGE_PLUGINS_LIDAR_PLOT_H_
#define LOCFORGE_PLUGINS_LIDAR_PLOT_H_

#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

namespace locforge::lidar {

struct PlotSequence {
  std::string name;
  std::vector<int> ids;               // node ids, in order
  std::vector<Eigen::Vector2d> xy;    // positions of those nodes
};

// Two panels ("before", "after"); loops are pairs of node ids drawn in red.
std::string TopDownSvg(const std::vector<PlotSequence>& before, const std::vector<PlotSequence>& after,
                       const std::vector<std::pair<int, int>>& loops);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_LIDAR_PLOT_H_

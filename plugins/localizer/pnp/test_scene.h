// Synthetic scenes shared by the pnp tests.
#ifndef LOCFORGE_PLUGINS_LOCALIZER_PNP_TEST_SCENE_H_
#define LOCFORGE_PLUGINS_LOCALIZER_PNP_TEST_SCENE_H_

#include <random>
#include <vector>

#include "locforge/pose.h"

namespace locforge::localization::testing {

// n points in front of `camera_from_world` (x, y in [-1.5, 1.5] m, depth in
// [min_depth, 8] m in the camera), returned in the world frame.
inline std::vector<Eigen::Vector3d> PointsInView(const Pose& camera_from_world, int n, std::mt19937& rng,
                                                 double min_depth = 2.0) {
  std::uniform_real_distribution<double> xy(-1.5, 1.5), z(min_depth, 8);
  std::vector<Eigen::Vector3d> out;
  const Pose world_from_camera = camera_from_world.Inverse();
  for (int i = 0; i < n; ++i) out.push_back(world_from_camera * Eigen::Vector3d(xy(rng), xy(rng), z(rng)));
  return out;
}

}  // namespace locforge::localization::testing

#endif  // LOCFORGE_PLUGINS_LOCALIZER_PNP_TEST_SCENE_H_

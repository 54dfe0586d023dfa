// Tests only: scans of a floor plan of vertical walls (2-D segments), cast
// from a platform pose, with known geometry.
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SYNTHETIC_FLOOR_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SYNTHETIC_FLOOR_H_

#include <cmath>
#include <limits>
#include <vector>

#include "cloud.h"

namespace locforge::lidar {

struct Segment {
  Eigen::Vector2d a, b;
};

// Rays every `azimuth_step_deg` from the rig origin; every wall is hit at
// each of `heights` (rig frame z); points returned in the rig frame.
inline Cloud SimulateFloorScan(const std::vector<Segment>& walls, const Pose& T_world_rig,
                               double azimuth_step_deg = 0.4, const std::vector<double>& heights = {0.5, 1.0, 1.5, 2.2},
                               double max_range = 40) {
  Cloud out;
  const Eigen::Vector2d o = T_world_rig.t.head<2>();
  const double heading = std::atan2(T_world_rig.q.toRotationMatrix()(1, 0), T_world_rig.q.toRotationMatrix()(0, 0));
  const Pose T_rig_world = T_world_rig.Inverse();
  for (double az = 0; az < 360; az += azimuth_step_deg) {
    const double angle = heading + az * M_PI / 180;
    const Eigen::Vector2d d(std::cos(angle), std::sin(angle));
    double best = max_range;
    for (const Segment& s : walls) {
      // o + t d = s.a + u (s.b - s.a)
      const Eigen::Vector2d e = s.b - s.a;
      const double den = d.x() * (-e.y()) - d.y() * (-e.x());
      if (std::abs(den) < 1e-12) continue;
      const Eigen::Vector2d w = s.a - o;
      const double t = (w.x() * (-e.y()) - w.y() * (-e.x())) / den;
      const double u = (d.x() * w.y() - d.y() * w.x()) / den;
      if (t > 0.05 && u >= 0 && u <= 1 && t < best) best = t;
    }
    if (best >= max_range) continue;
    const Eigen::Vector2d hit = o + best * d;
    for (double z : heights) {
      const Eigen::Vector3d p = T_rig_world * Eigen::Vector3d(hit.x(), hit.y(), T_world_rig.t.z() + z);
      out.points.push_back(p.cast<float>());
    }
  }
  return out;
}

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SYNTHETIC_FLOOR_H_

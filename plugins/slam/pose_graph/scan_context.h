// Place recognition between LiDAR keyframes: Scan Context (Kim & Kim,
// "Scan Context: Egocentric Spatial Descriptor for Place Recognition within
// 3D Point Cloud Map", IROS 2018). A scan becomes a polar grid (rings x
// sectors around the sensor) holding the highest return of each bin; its ring
// key (occupancy per ring) does not change when the platform turns, so it
// ranks candidates, and the column shift that best aligns two grids gives
// their relative heading (Sec. III-C, eq. 5-6).
//
// Indoors the ceiling is everywhere at the same height: only returns in a
// height band below it describe the place.
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SCAN_CONTEXT_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SCAN_CONTEXT_H_

#include <Eigen/Core>
#include <string>
#include <vector>

#include "cloud.h"

namespace locforge::lidar {

struct ScanContextOptions {
  int rings = 20;               // radial bins
  int sectors = 60;             // azimuth bins (6 deg)
  double max_radius_m = 20;     // farther returns are ignored
  double min_height_m = 0.2;    // band of returns described, rig frame
  double max_height_m = 3.0;
  bool Check(std::string* why = nullptr) const;
};

struct ScanContext {
  Eigen::MatrixXf grid;      // rings x sectors: highest return above min_height_m (0: empty)
  Eigen::VectorXf ring_key;  // fraction of occupied sectors per ring
};

ScanContext MakeScanContext(const Cloud& scan, const ScanContextOptions& options);

struct ScanContextMatch {
  double distance = 1;  // eq. 6: mean cosine distance of the aligned columns, in [0, 1]
  double yaw = 0;       // rad: heading of b's frame in a's (p_a = Rz(yaw) p_b at the same place)
};
// The best column shift of b against a.
ScanContextMatch CompareScanContexts(const ScanContext& a, const ScanContext& b);

// Distance of two ring keys (L1, per ring): the cheap first ranking.
double RingKeyDistance(const ScanContext& a, const ScanContext& b);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SCAN_CONTEXT_H_

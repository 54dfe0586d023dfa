// Trajectory metrics as the evo tool computes them (evo's core/metrics.py,
// core/sync.py, core/geometry.py), so our numbers agree with evo's:
//  - poses are T_world_device (TUM / KITTI files hold them; kapture holds the inverse);
//  - association: for each stamp of the shorter trajectory the nearest stamp of the
//    longer one, kept when |dt| <= max_diff;
//  - alignment: Umeyama (1991) on positions, SE(3) or Sim(3) (scale);
//  - APE: per pose E = P_ref^-1 P_est; translation ||t_ref - t_est||, rotation angle(E);
//  - RPE: E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) over pairs (i, j) chosen on the estimate
//    (every `delta` frames, or each time `delta` metres of path have been travelled);
//  - statistics: rmse, mean, median, std (population), min, max, sse.
#ifndef LOCFORGE_PLUGINS_EVAL_TRAJECTORY_METRICS_H_
#define LOCFORGE_PLUGINS_EVAL_TRAJECTORY_METRICS_H_

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "locforge/fs.h"
#include "locforge/pose.h"

namespace locforge::eval {

struct StampedPose {
  double time = 0;  // seconds
  Pose T_world_device;
  // The matrix as read from a KITTI file (rotation not quite orthonormal):
  // RPE uses it as evo does (inverse = transpose), to agree to 1e-9.
  std::optional<Eigen::Matrix4d> raw;
  Eigen::Matrix4d Matrix() const { return raw ? *raw : T_world_device.Matrix(); }
};
using Trajectory = std::vector<StampedPose>;

// TUM: "t tx ty tz qx qy qz qw" per line ('#' comments). KITTI: 12 numbers
// (3x4 row-major) per line, stamped 0, 1, 2... Errors name file, line, field.
Trajectory ReadTum(const fs::path& path);
Trajectory ReadKitti(const fs::path& path);
// kapture trajectories.txt of one device (T_device_world inverted), times in seconds.
Trajectory ReadKaptureTrajectory(const fs::path& kapture_root, const std::string& device,
                                 double seconds_per_unit);
std::string FormatTum(const Trajectory& t);
std::string FormatKitti(const Trajectory& t);

// Reduces both to their associated poses (evo's associate_trajectories).
void Associate(double max_diff, Trajectory* reference, Trajectory* estimate);

enum class Alignment { kNone, kFirst, kSE3, kSim3 };
// Umeyama's least-squares similarity y ~ s R x + t over positions.
struct Similarity {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  double scale = 1;
};
Similarity Umeyama(const std::vector<Eigen::Vector3d>& x, const std::vector<Eigen::Vector3d>& y, bool with_scale);
// Moves `estimate` onto `reference` (kFirst: the first estimate pose onto the first reference pose).
Similarity Align(Alignment alignment, const Trajectory& reference, Trajectory* estimate);

struct Statistics {
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0, sse = 0;
  size_t count = 0;
};
Statistics ComputeStatistics(std::vector<double> errors);

struct Errors {
  std::vector<double> translation;  // m
  std::vector<double> rotation;     // deg
};
Errors AbsolutePoseErrors(const Trajectory& reference, const Trajectory& estimate);

enum class DeltaUnit { kFrames, kMeters };
std::vector<std::pair<size_t, size_t>> RelativePairs(const Trajectory& estimate, double delta, DeltaUnit unit,
                                                     bool all_pairs = false);
Errors RelativePoseErrors(const Trajectory& reference, const Trajectory& estimate, double delta, DeltaUnit unit,
                          bool all_pairs = false);

}  // namespace locforge::eval

#endif  // LOCFORGE_PLUGINS_EVAL_TRAJECTORY_METRICS_H_

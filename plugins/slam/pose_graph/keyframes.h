// Keyframes of the LiDAR SLAM: which scans enter the pose graph (the first
// of every motion segment, then one per keyframe_distance_m travelled or
// keyframe_angle_deg turned), what each carries, and the motion model that
// guesses their relative poses (wheel odometry, or constant velocity for
// recordings without it).
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_KEYFRAMES_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_KEYFRAMES_H_

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "cloud.h"
#include "locforge/kapture/types.h"
#include "scan_context.h"
#include "wheel_odometry.h"

namespace locforge::lidar {

struct Keyframe {
  int id = 0;
  Timestamp timestamp = 0;
  std::string sequence;
  Cloud cloud, rough;         // full, and downsampled for the rough loop check
  ScanContext context;        // place descriptor (scan_context.h)
  double travelled = 0;       // m since the sequence's start: odometry, or estimated
  // Where `cloud` is read from when it is not kept in memory (empty `cloud`):
  // a slam/sequences part file and the cloud's byte offset in it (slam_part.h).
  fs::path cloud_file;
  uint64_t cloud_offset = 0;
};

// "undistorted/<seq>/..." -> "<seq>"; a path without a folder -> "".
std::string SequenceOfScan(const std::string& path);

// Motion between scans: wheel odometry when given, else nothing but time.
class MotionModel {
 public:
  // odometry: null for constant velocity; max_scan_gap_s: constant velocity,
  // a larger gap between scans starts a new segment.
  MotionModel(const WheelOdometry* odometry, double max_scan_gap_s, double seconds_per_unit)
      : odometry_(odometry), max_gap_(max_scan_gap_s), seconds_per_unit_(seconds_per_unit) {}
  bool has_odometry() const { return odometry_ != nullptr; }
  const WheelOdometry* odometry() const { return odometry_; }
  bool Covers(Timestamp t) const;
  // Same sequence and segment (odometry segment, or no gap above max_scan_gap_s).
  bool SameSegment(const std::string& seq_a, Timestamp a, const std::string& seq_b, Timestamp b) const;
  // Odometry motion T_a_b (identity without odometry) and distance driven.
  Pose Relative(Timestamp a, Timestamp b) const;
  double Distance(Timestamp a, Timestamp b) const;

 private:
  const WheelOdometry* odometry_;
  double max_gap_, seconds_per_unit_;
};

struct ScanStamp {
  Timestamp timestamp = 0;
  std::string sequence;
};

struct KeyframeChoice {
  size_t scan = 0;            // index into the scans
  bool segment_start = false; // first keyframe of a sequence or motion segment
  double travelled = 0;       // odometry distance since the segment's start (m; 0 without odometry)
};

// Scans in time order -> keyframes. With odometry: scans it does not cover
// are skipped, a scan is a keyframe when the motion since the last one
// reaches either threshold; without odometry every scan is one.
std::vector<KeyframeChoice> ChooseKeyframes(const std::vector<ScanStamp>& scans, const MotionModel& motion,
                                            double keyframe_distance_m, double keyframe_angle_rad);

// Wheel odometry's turns, calibrated against the registrations of the same
// keyframe pairs: registered yaw = k * odometry yaw, least squares over a
// sequence's pairs (unequal or misjudged wheel radii scale every turn alike).
struct YawScaleFit {
  double k = 1;            // the fitted factor
  double turned_rad = 0;   // sum of |odometry yaw| it rests on
  bool applied = false;    // enough turning and a plausible factor
};
struct YawScaleOptions {
  double min_turned_rad = M_PI;  // half a spin, at least
  double max_deviation = 0.2;    // |k - 1| beyond this is a failure, not wheels
};
// pairs: (odometry yaw, registered yaw) in rad, signed about the vertical.
YawScaleFit FitYawScale(const std::vector<std::pair<double, double>>& pairs, const YawScaleOptions& options = {});

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_KEYFRAMES_H_

// Differential-drive wheel odometry from cumulative encoder ticks.
//
// The platform frame has its origin at the centre of the wheel axle, x forward,
// y left, z up. Each encoder interval is integrated with the midpoint (second
// order Runge-Kutta) rule of a unicycle:
//   d_l = 2 pi r dticks_l / ppr, d_r = 2 pi r dticks_r / ppr
//   ds = (d_l + d_r) / 2, dtheta = (d_r - d_l) / axle
//   x += ds cos(theta + dtheta / 2), y += ds sin(theta + dtheta / 2), theta += dtheta
// Poses between encoder samples are interpolated on SE(3) (pose.h Interpolate).
// A recording with several sequences has one segment per sequence (a time gap
// or ticks going backwards starts a new one); relative motion is only defined
// inside a segment.
#ifndef LOCFORGE_PLUGINS_COMMON_LIDAR_WHEEL_ODOMETRY_H_
#define LOCFORGE_PLUGINS_COMMON_LIDAR_WHEEL_ODOMETRY_H_

#include <string>
#include <vector>

#include "locforge/fs.h"
#include "locforge/pose.h"

namespace locforge::lidar {

struct WheelParams {
  double radius = 0.1;          // Wheel radius in metres.
  double axle = 0.5;            // Distance between the wheels in metres.
  double pulses_per_rev = 1024; // Encoder pulses per wheel revolution.
  bool Check(std::string* why) const;
};

struct WheelTicks {
  Timestamp timestamp = 0;
  int64_t left = 0, right = 0;  // cumulative
};

class WheelOdometry {
 public:
  // `seconds_per_unit`: duration of one timestamp unit (1e-6 for microseconds).
  // `max_gap_s`: a larger gap between two encoder samples starts a new segment.
  WheelOdometry(const WheelParams& params, std::vector<WheelTicks> ticks,
                double seconds_per_unit = 1e-6, double max_gap_s = 1.0);

  // Reads sensors/records_wheel_encoder.txt of a kapture. Wheel parameters come
  // from the wheel_encoder sensor of sensors.txt (radius, axle, pulses_per_rev)
  // unless `override_params` has values > 0.
  static WheelOdometry FromKapture(const fs::path& root, const WheelParams& override_params = {0, 0, 0},
                                   const std::string& sensor_id = "");

  // T_odom_platform at `t` (in timestamp units, fractional allowed). Throws
  // Error outside the recorded span (up to 0.2 s beyond it is held constant).
  Pose PlatformPose(double t) const;
  // T_a_b: the platform at time b seen from the platform at time a. Both in
  // the same segment, else Error.
  Pose Relative(double t_a, double t_b) const;
  bool Covers(double t) const;
  // True when t_a and t_b are in the same segment.
  bool SameSegment(double t_a, double t_b) const;
  // Travelled distance (m) between two times of one segment.
  double Distance(double t_a, double t_b) const;

  const WheelParams& params() const { return params_; }
  size_t num_segments() const { return segments_.size(); }

 private:
  struct Sample {
    double t;
    Pose pose;        // T_odom_platform
    double distance;  // travelled since the segment start
  };
  using Segment = std::vector<Sample>;
  const Segment& SegmentOf(double t) const;
  static Sample At(const Segment& s, double t);

  WheelParams params_;
  std::vector<Segment> segments_;
  double margin_units_ = 0;
};

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_COMMON_LIDAR_WHEEL_ODOMETRY_H_

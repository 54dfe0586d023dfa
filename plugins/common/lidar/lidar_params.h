// What the LiDAR stages share in their parameters: the recording they read
// (a path parameter or the `recording` input) and the wheel parameters that
// may override sensors.txt.
#ifndef LOCFORGE_PLUGINS_COMMON_LIDAR_LIDAR_PARAMS_H_
#define LOCFORGE_PLUGINS_COMMON_LIDAR_LIDAR_PARAMS_H_

#include <string>

#include "locforge/plugin.h"
#include "wheel_odometry.h"

namespace locforge::lidar {

// The recording a stage reads: its `recording` input when wired (e.g. from
// source/simulator in the same graph), else its `dataset` parameter; a clear
// ParamError when neither or both are given.
fs::path RecordingOf(RunContext& ctx, const std::string& dataset_param, const std::string& stage);

// The optional input port RecordingOf reads.
inline PortMeta RecordingPort() {
  return {"recording", "kapture.dataset", "the recording, instead of the dataset parameter", LF_PORT_OPTIONAL};
}

// Wheel parameters; 0 keeps the value of the wheel_encoder sensor in sensors.txt.
struct WheelOverrides {
  double wheel_radius_m = 0;
  double wheel_axle_m = 0;
  double pulses_per_rev = 0;
  WheelParams Params() const { return {wheel_radius_m, wheel_axle_m, pulses_per_rev}; }
};

template <typename O>
void DeclareWheelOverrides(ParamSchema<O>& s, WheelOverrides O::*wheels) {
  s.Add("wheel_radius_m", wheels, &WheelOverrides::wheel_radius_m, "Wheel radius (m); 0: from sensors.txt").Min(0);
  s.Add("wheel_axle_m", wheels, &WheelOverrides::wheel_axle_m, "Axle length (m); 0: from sensors.txt").Min(0);
  s.Add("pulses_per_rev", wheels, &WheelOverrides::pulses_per_rev,
        "Encoder pulses per wheel revolution; 0: from sensors.txt").Min(0);
}

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_COMMON_LIDAR_LIDAR_PARAMS_H_

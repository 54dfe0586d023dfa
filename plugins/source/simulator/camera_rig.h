// The sensor rig of the mapping platform (defaults from the paper's sensor
// table): six industrial cameras (2592x2048, 79.4x63 deg, 2.5 Hz, global
// shutter) at 60 deg intervals tilted 10 deg up, four smartphones (2160x2880
// portrait, 77 deg diagonal, 1 Hz) slightly above them, a horizontal and a
// vertical VLP-16, and the wheel encoders. Cameras run on their own clocks
// (constant offset + per-frame jitter).
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_CAMERA_RIG_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_CAMERA_RIG_H_

#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "lidar.h"
#include "locforge/pose.h"
#include "platform.h"

namespace locforge::sim {

// Pinhole intrinsics (pixel centres at +0.5, x right, y down, z forward).
struct PinholeCamera {
  int width = 0, height = 0;
  double fx = 1, fy = 1, cx = 0, cy = 0;

  static PinholeCamera FromFov(int width, int height, double hfov_deg, double vfov_deg);
  static PinholeCamera FromDiagonalFov(int width, int height, double dfov_deg);
  Eigen::Vector2d Project(const Eigen::Vector3d& p_camera) const {
    return {fx * p_camera.x() / p_camera.z() + cx, fy * p_camera.y() / p_camera.z() + cy};
  }
  // Ray through pixel (x, y) on the z = 1 plane.
  Eigen::Vector3d Ray(double x, double y) const { return {(x - cx) / fx, (y - cy) / fy, 1}; }
};

struct CameraOptions {
  std::string id;                 // kapture sensor id, e.g. "ind_0", "phone_2"
  std::string model;              // human-readable name
  PinholeCamera intrinsics;
  Pose T_platform_camera;         // camera-to-platform (CAD)
  double rate_hz = 2.5;
  double phase_s = 0;             // first nominal trigger
  double clock_offset_s = 0;      // camera clock minus true time
  double jitter_s = 0.002;        // 1 sigma of the capture-time jitter
};

struct RigOptions {
  double image_scale = 1.0;       // resolution factor applied to every camera
  bool industrial = true;         // the six industrial cameras
  bool phones = true;             // the four smartphones
  double clock_offset_sigma_s = 0.005;
  double jitter_sigma_s = 0.002;
  double lidar_azimuth_resolution_deg = 0.2;
  double lidar_range_sigma = 0.015;
  bool Check(std::string* why) const;
};

struct Rig {
  std::vector<CameraOptions> cameras;
  std::vector<LidarOptions> lidars;   // "lidar_h" (horizontal), "lidar_v" (vertical push-broom)
  WheelOptions wheels;
};

// A camera looking at azimuth (counter-clockwise from the platform's x axis),
// tilted up by `tilt_deg`, at `position` on the platform.
Pose CameraMount(double azimuth_deg, double tilt_deg, const Eigen::Vector3d& position);

// The rig; clock offsets and trigger phases are drawn from `seed`.
Rig MakeRig(const RigOptions& options, uint64_t seed);

struct Capture {
  int index = 0;            // frame number in the sequence
  double true_time = 0;     // when the shutter opened (trajectory clock, s)
  double stamp = 0;         // the camera's timestamp: nominal trigger + clock offset (s)
};

// The captures of a camera over [0, duration).
std::vector<Capture> CaptureTimes(const CameraOptions& camera, double duration, uint64_t seed);

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_CAMERA_RIG_H_

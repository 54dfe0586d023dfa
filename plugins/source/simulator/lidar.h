// Velodyne VLP-16 style spinning LiDAR: 16 rings over [-15, +15] deg, one
// column of firings per azimuth step, per-point timestamps. Each point is cast
// from the sensor pose at its own firing time (so scans carry the motion
// distortion of the platform) and against the people at that instant, and is
// reported in the sensor frame at that time, as a real sensor does.
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_LIDAR_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_LIDAR_H_

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "locforge/pose.h"
#include "platform.h"
#include "raycast.h"

namespace locforge::sim {

struct LidarOptions {
  std::string id = "lidar";
  Pose T_platform_lidar;            // sensor-to-platform (CAD extrinsics)
  int rings = 16;
  double min_elevation_deg = -15;
  double max_elevation_deg = 15;
  double azimuth_resolution_deg = 0.2;
  double rate_hz = 10;              // rotations per second
  double range_sigma = 0.015;       // 1 sigma range noise (m)
  double min_range = 0.4, max_range = 100;
  double ring_firing_s = 2.304e-6;  // delay between consecutive lasers of a column
  bool Check(std::string* why) const;
  int columns() const { return static_cast<int>(std::lround(360.0 / azimuth_resolution_deg)); }
};

struct LidarPoint {
  Eigen::Vector3f xyz;  // sensor frame at the firing time
  float intensity = 0;  // 0-255
  uint16_t ring = 0;    // 0 = lowest elevation
  double time = 0;      // seconds after the scan start
};

struct LidarScan {
  double start = 0;  // seconds on the trajectory clock
  std::vector<LidarPoint> points;
};

// Unit direction of a laser in the sensor frame (x forward, z up, azimuth counter-clockwise).
Eigen::Vector3d LaserDirection(const LidarOptions& lidar, int ring, int column);

// `reference_raycast` casts every ray with World::Cast (QuadBvh, every
// person): the slow reference that the default (World::CastNear) equals bit
// for bit.
LidarScan SimulateScan(const World& world, const Trajectory& trajectory, const LidarOptions& lidar,
                       double start, uint64_t seed, bool reference_raycast = false);

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_LIDAR_H_

#include "lidar.h"

#include <cmath>
#include <random>

namespace locforge::sim {
namespace {
constexpr double kDeg = 3.14159265358979323846 / 180;
}  // namespace

bool LidarOptions::Check(std::string* why) const {
  if (rings < 1) return *why = "lidar needs at least one ring", false;
  if (max_elevation_deg < min_elevation_deg) return *why = "lidar elevation range is empty", false;
  if (azimuth_resolution_deg <= 0 || azimuth_resolution_deg > 90)
    return *why = "lidar azimuth resolution must be in (0, 90] deg", false;
  if (rate_hz <= 0 || range_sigma < 0 || min_range < 0 || max_range <= min_range)
    return *why = "lidar rate, noise or range limits are invalid", false;
  return true;
}

Eigen::Vector3d LaserDirection(const LidarOptions& lidar, int ring, int column) {
  const double elevation =
      lidar.rings == 1 ? 0
                       : (lidar.min_elevation_deg + (lidar.max_elevation_deg - lidar.min_elevation_deg) *
                                                        ring / (lidar.rings - 1)) * kDeg;
  const double azimuth = column * lidar.azimuth_resolution_deg * kDeg;
  return {std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth),
          std::sin(elevation)};
}

LidarScan SimulateScan(const World& world, const Trajectory& trajectory, const LidarOptions& lidar,
                       double start, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0, lidar.range_sigma);
  LidarScan scan;
  scan.start = start;
  const int columns = lidar.columns();
  const double column_s = 1.0 / (lidar.rate_hz * columns);
  scan.points.reserve(static_cast<size_t>(columns) * lidar.rings);
  for (int c = 0; c < columns; ++c) {
    const double column_time = c * column_s;
    // People move < 0.1 mm during one column: one snapshot per column.
    const std::vector<Cylinder> people = world.crowd().At(start + column_time);
    for (int r = 0; r < lidar.rings; ++r) {
      const double time = column_time + r * lidar.ring_firing_s;
      const Pose T_world_lidar = trajectory.PoseAt(start + time) * lidar.T_platform_lidar;
      const Eigen::Vector3d d_lidar = LaserDirection(lidar, r, c);
      Hit hit;
      if (!world.Cast(T_world_lidar.t, T_world_lidar.q * d_lidar, people, &hit)) continue;
      const double range = hit.t + noise(rng);
      if (hit.t < lidar.min_range || hit.t > lidar.max_range) continue;
      // Intensity: surface brightness times the cosine of incidence.
      const Eigen::Vector3f albedo = world.Albedo(hit, 0.01 * hit.t);
      const double cos_inc = std::abs(hit.normal.dot(T_world_lidar.q * d_lidar));
      LidarPoint p;
      p.xyz = (d_lidar * range).cast<float>();
      p.intensity = static_cast<float>(albedo.mean() * cos_inc);
      p.ring = static_cast<uint16_t>(r);
      p.time = time;
      scan.points.push_back(p);
    }
  }
  return scan;
}

}  // namespace locforge::sim

#include "lidar.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <utility>

#include "locforge/units.h"

namespace locforge::sim {
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
                       double start, uint64_t seed, bool reference_raycast) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0, lidar.range_sigma);
  LidarScan scan;
  scan.start = start;
  const int columns = lidar.columns();
  const double column_s = 1.0 / (lidar.rate_hz * columns);
  scan.points.reserve(static_cast<size_t>(columns) * lidar.rings);

  // People near the rays: a grid of where each person can be during the
  // scan (within speed x scan time of where it stands at the scan start).
  const Crowd& crowd = world.crowd();
  const int num_people = static_cast<int>(crowd.people().size());
  const double span = columns * column_s;
  std::vector<PeopleGrid::Bound> bounds(reference_raycast ? 0 : num_people);
  for (int i = 0; i < static_cast<int>(bounds.size()); ++i) {
    const auto cylinders = crowd.Cylinders(i, crowd.PositionAt(i, start));
    PeopleGrid::Bound& b = bounds[i];
    b.center = cylinders[0].center;
    b.radius = std::max(0.0, crowd.people()[i].speed) * span;
    b.z0 = std::numeric_limits<double>::infinity();
    b.z1 = -b.z0;
    double radius = 0;
    for (const Cylinder& c : cylinders) {
      radius = std::max(radius, c.radius);
      b.z0 = std::min(b.z0, c.z0);
      b.z1 = std::max(b.z1, c.z1);
    }
    b.radius += radius;
  }
  const PeopleGrid grid(bounds);
  // The cylinders of the people the current column's rays may hit, at its
  // instant, computed on first use.
  std::vector<std::array<Cylinder, 2>> cylinders(grid.num_items());
  std::vector<int> cylinders_column(grid.num_items(), -1);
  std::vector<int> candidates;

  for (int c = 0; c < columns; ++c) {
    const double column_time = c * column_s;
    const double people_time = start + column_time;
    // People move < 0.1 mm during one column: one snapshot per column.
    const std::vector<Cylinder> people = reference_raycast ? crowd.At(people_time) : std::vector<Cylinder>();
    const auto cylinders_of = [&](int k) {
      if (cylinders_column[k] != c) {
        cylinders[k] = crowd.Cylinders(k, crowd.PositionAt(k, people_time));
        cylinders_column[k] = c;
      }
      return std::make_pair(cylinders[k].data(), cylinders[k].data() + cylinders[k].size());
    };
    for (int r = 0; r < lidar.rings; ++r) {
      const double time = column_time + r * lidar.ring_firing_s;
      const Pose T_world_lidar = trajectory.PoseAt(start + time) * lidar.T_platform_lidar;
      const Eigen::Vector3d d_lidar = LaserDirection(lidar, r, c);
      const Eigen::Vector3d d_world = T_world_lidar.q * d_lidar;
      Hit hit;
      if (reference_raycast ? !world.Cast(T_world_lidar.t, d_world, people, &hit)
                            : !world.CastNear(T_world_lidar.t, d_world, grid, cylinders_of, &candidates, &hit))
        continue;
      const double range = hit.t + noise(rng);
      if (hit.t < lidar.min_range || hit.t > lidar.max_range) continue;
      // Intensity: surface brightness times the cosine of incidence.
      const Eigen::Vector3f albedo = world.Albedo(hit, 0.01 * hit.t);
      const double cos_inc = std::abs(hit.normal.dot(d_world));
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

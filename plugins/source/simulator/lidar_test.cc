#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "lidar.h"
#include "people.h"

namespace locforge::sim {
namespace {

constexpr double kSigma = 0.015;

// Distance from a point to a rectangle.
double DistanceToQuad(const Quad& q, const Eigen::Vector3d& p) {
  const Eigen::Vector3d rel = p - q.origin;
  const double a = std::clamp(rel.dot(q.u_edge) / q.u_edge.squaredNorm(), 0.0, 1.0);
  const double b = std::clamp(rel.dot(q.v_edge) / q.v_edge.squaredNorm(), 0.0, 1.0);
  return (q.origin + a * q.u_edge + b * q.v_edge - p).norm();
}

// Distance from a point to the surface of a closed vertical cylinder.
double DistanceToCylinder(const Cylinder& c, const Eigen::Vector3d& p) {
  const double r = (p.head<2>() - c.center).norm();
  const double dz = p.z() < c.z0 ? c.z0 - p.z() : p.z() > c.z1 ? p.z() - c.z1 : 0;
  const double dr = std::max(0.0, r - c.radius);
  if (dz == 0 && dr == 0) return std::min({c.radius - r, p.z() - c.z0, c.z1 - p.z()});
  return std::hypot(dz, dr);
}

struct Fixture {
  Scene scene;
  Crowd crowd;
  TextureLibrary textures{64};
  std::unique_ptr<World> world;
  Trajectory trajectory;

  Fixture() {
    FloorOptions floor;  // a 2x1 block floor, 20 x 15 m
    const SceneSpec spec = GenerateFloor(floor, 3);
    scene = BuildScene(spec);
    crowd = MakeCrowd(spec, 4.0, 11);
    world = std::make_unique<World>(scene, crowd, &textures, 0);
    // Along the bottom corridor with a spin at its middle: fast rotation during scans.
    const Eigen::Vector2d a = spec.walk.nodes[0], b = spec.walk.nodes[1];
    trajectory = Drive({a, 0.5 * (a + b), b}, {false, true, false}, 0, MotionLimits{}, 60, 0.1);
  }
};

Pose HorizontalMount() { return Pose(Eigen::Quaterniond::Identity(), {0, 0, 0.9}); }

TEST(Lidar, PointsReprojectOntoSceneSurfacesWithinTheNoise) {
  Fixture f;
  LidarOptions lidar;
  lidar.T_platform_lidar = HorizontalMount();
  lidar.azimuth_resolution_deg = 0.4;  // keep the test fast
  // The scans while spinning in place: the worst motion distortion.
  double spin_time = 0;
  for (const auto& s : f.trajectory.states)
    if (std::abs(s.w) > 1.4 && std::abs(s.v) < 1e-6) { spin_time = s.t; break; }
  ASSERT_GT(spin_time, 0);
  size_t total = 0, within = 0, within_static = 0, on_people = 0;
  double sum_sq = 0, sum = 0;
  for (int k = 0; k < 3; ++k) {
    const double start = spin_time + 0.1 * k;
    const LidarScan scan = SimulateScan(*f.world, f.trajectory, lidar, start, 100 + k);
    ASSERT_GT(scan.points.size(), 0.8 * lidar.columns() * lidar.rings);
    const Pose T_start = f.trajectory.PoseAt(start) * lidar.T_platform_lidar;
    for (size_t i = 0; i < scan.points.size(); i += 3) {
      const LidarPoint& p = scan.points[i];
      ASSERT_GE(p.time, 0);
      ASSERT_LT(p.time, 0.1);
      const double t = start + p.time;
      const Pose T = f.trajectory.PoseAt(t) * lidar.T_platform_lidar;
      const Eigen::Vector3d world_point = T * p.xyz.cast<double>();
      const auto people = f.crowd.At(t);
      double d = 1e9;
      for (const auto& q : f.world->quads()) d = std::min(d, DistanceToQuad(q, world_point));
      for (const auto& c : people) {
        const double dc = DistanceToCylinder(c, world_point);
        if (dc < d) d = dc;
      }
      // Along-ray residual against a fresh cast from the true pose at that instant.
      Hit hit;
      const Eigen::Vector3d dir = T.q * p.xyz.cast<double>().normalized();
      ASSERT_TRUE(f.world->Cast(T.t, dir, people, &hit));
      const double residual = p.xyz.cast<double>().norm() - hit.t;
      sum += residual;
      sum_sq += residual * residual;
      on_people += hit.person >= 0;
      ++total;
      within += d < 4 * kSigma;
      // Negative control: ignoring the motion (scan-start pose for every point).
      const Eigen::Vector3d undistorted = T_start * p.xyz.cast<double>();
      double ds = 1e9;
      for (const auto& q : f.world->quads()) ds = std::min(ds, DistanceToQuad(q, undistorted));
      for (const auto& c : people) ds = std::min(ds, DistanceToCylinder(c, undistorted));
      within_static += ds < 4 * kSigma;
    }
  }
  const double frac = double(within) / total, frac_static = double(within_static) / total;
  const double mean = sum / total, stddev = std::sqrt(sum_sq / total - mean * mean);
  std::printf("lidar: %zu points, %.2f %% within 4 sigma of a surface (%.2f %% without motion "
              "compensation), range residual mean %.4f m, std %.4f m, %zu on people\n",
              total, 100 * frac, 100 * frac_static, mean, stddev, on_people);
  EXPECT_GT(frac, 0.99);
  EXPECT_LT(frac_static, 0.9);
  EXPECT_NEAR(mean, 0, 0.002);
  EXPECT_NEAR(stddev, kSigma, 0.1 * kSigma);
  EXPECT_GT(on_people, 0u);
}

TEST(Lidar, VerticalPushBroomSeesFloorAndCeiling) {
  Fixture f;
  LidarOptions lidar;
  lidar.azimuth_resolution_deg = 1.0;
  // Spin axis along the platform's x axis (forward).
  lidar.T_platform_lidar = Pose(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY())),
                                {0, 0, 1.9});
  const LidarScan scan = SimulateScan(*f.world, f.trajectory, lidar, 1.0, 1);
  double min_z = 1e9, max_z = -1e9;
  for (const auto& p : scan.points) {
    const Eigen::Vector3d w = f.trajectory.PoseAt(1.0 + p.time) * lidar.T_platform_lidar * p.xyz.cast<double>();
    min_z = std::min(min_z, w.z());
    max_z = std::max(max_z, w.z());
  }
  EXPECT_NEAR(min_z, 0, 0.1);
  EXPECT_NEAR(max_z, f.scene.spec.height, 0.1);
}

TEST(Lidar, ScanGeometryMatchesTheVlp16) {
  LidarOptions lidar;
  EXPECT_EQ(lidar.columns(), 1800);
  EXPECT_NEAR(std::asin(LaserDirection(lidar, 0, 0).z()) * 180 / M_PI, -15, 1e-9);
  EXPECT_NEAR(std::asin(LaserDirection(lidar, 15, 0).z()) * 180 / M_PI, 15, 1e-9);
  EXPECT_NEAR(LaserDirection(lidar, 8, 450).y(), std::cos(1 * M_PI / 180), 1e-9);
}

}  // namespace
}  // namespace locforge::sim

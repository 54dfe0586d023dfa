#include "point_uncertainty.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <iostream>
#include <random>

#include "absolute_pose.h"

namespace locforge::localization {
namespace {

constexpr double kFocal = 1000;

// Camera at `centre` looking at `target` (y roughly down), as camera_from_world.
Pose LookAt(const Eigen::Vector3d& centre, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - centre).normalized();
  const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
  Eigen::Matrix3d world_from_camera;
  world_from_camera << x, z.cross(x), z;
  const Eigen::Matrix3d r = world_from_camera.transpose();
  return Pose(Eigen::Quaterniond(r), -(r * centre));
}

Eigen::Vector2d Pixel(const Pose& camera_from_world, const Eigen::Vector3d& x) {
  return kFocal * (camera_from_world * x).hnormalized();
}

// Least-squares triangulation from pixels (Gauss-Newton from `start`).
Eigen::Vector3d Triangulate(const std::vector<Pose>& views, const std::vector<Eigen::Vector2d>& pixels,
                            Eigen::Vector3d x) {
  for (int iteration = 0; iteration < 10; ++iteration) {
    Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < views.size(); ++i) {
      const Eigen::Vector3d p = views[i] * x;
      Eigen::Matrix<double, 2, 3> j;
      j << 1 / p.z(), 0, -p.x() / (p.z() * p.z()), 0, 1 / p.z(), -p.y() / (p.z() * p.z());
      j = kFocal * j * views[i].R();
      const Eigen::Vector2d r = Pixel(views[i], x) - pixels[i];
      h += j.transpose() * j;
      g += j.transpose() * r;
    }
    x -= h.ldlt().solve(g);
  }
  return x;
}

// Two views 0.3 m apart looking at a point 6 m away (a 2.9 deg angle): the
// predicted covariance matches the spread of points triangulated from 1 px
// noisy pixels, along the rays (poorly known) and across them (well known).
TEST(PointUncertainty, CovarianceMatchesMonteCarloTriangulation) {
  const Eigen::Vector3d point(0.2, -0.1, 6.0);
  const std::vector<Pose> views = {LookAt({-0.15, 0, 0}, point), LookAt({0.15, 0, 0}, point)};
  std::vector<MapView> map_views;
  for (const Pose& v : views) map_views.push_back({v.Center(), kFocal});
  const Eigen::Matrix3d predicted = TriangulationCovariance(point, map_views);

  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 1.0);
  const int samples = 4000;
  Eigen::Matrix3d measured = Eigen::Matrix3d::Zero();
  for (int s = 0; s < samples; ++s) {
    std::vector<Eigen::Vector2d> pixels;
    for (const Pose& v : views) pixels.push_back(Pixel(v, point) + Eigen::Vector2d(noise(rng), noise(rng)));
    const Eigen::Vector3d e = Triangulate(views, pixels, point) - point;
    measured += e * e.transpose() / samples;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(predicted);
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d axis = eigen.eigenvectors().col(k);
    const double want = axis.dot(predicted * axis), got = axis.dot(measured * axis);
    EXPECT_NEAR(got / want, 1.0, 0.1) << "axis " << k << ": predicted " << want << ", measured " << got;
  }
  // Along the mean ray the standard deviation is ~ d^2 / (f b) = 0.12 m; across, ~ d / f = 6 mm.
  EXPECT_GT(eigen.eigenvalues()(2), 100 * eigen.eigenvalues()(1));
}

// Without a point's uncertainty the whitening is the identity; with it, a
// query looking along the poorly known direction sees little of it, a query
// looking across it sees it all.
TEST(PointUncertainty, WhiteningFollowsTheViewingDirection) {
  const Eigen::Vector3d point(0, 0, 6.0);
  const std::vector<MapView> map_views = {{{-0.15, 0, 0}, kFocal}, {{0.15, 0, 0}, kFocal}};
  const Eigen::Matrix3d covariance = TriangulationCovariance(point, map_views);
  const Pose along = LookAt({0, 0, -1}, point), across = LookAt({7, 0, 6}, point);
  EXPECT_TRUE(ReprojectionWhitening(along, kFocal, point, Eigen::Matrix3d::Zero()).isIdentity(0));
  // The determinant: the product of the weights of the two image axes.
  const double along_weight = ReprojectionWhitening(along, kFocal, point, covariance).determinant();
  const double across_weight = ReprojectionWhitening(across, kFocal, point, covariance).determinant();
  EXPECT_GT(along_weight, 0.6);  // ~0.73: the point's small error across its rays adds to the pixel's
  EXPECT_LT(across_weight, 0.1 * along_weight);  // ~0.05: its depth error seen sideways
}

// A map of points triangulated by pairs of views at small angles (each point
// displaced by a draw from its own covariance, 1 px pixel noise), a query
// seeing them from 40 deg aside with 1 px noise: refined with each residual
// whitened by its point's covariance, the pose is closer to the truth than
// refined with every point taken as exact (the maximum-likelihood estimate
// against the unweighted one), over 100 scenes.
TEST(PointUncertainty, WeighedRefinementIsMoreAccurate) {
  std::mt19937 rng(17);
  std::normal_distribution<double> gauss(0, 1);
  std::uniform_real_distribution<double> uniform(-1, 1), depth(4, 10), baseline(0.1, 1.0);
  const Pose query = LookAt(Eigen::Vector3d(5, 0.3, 1), Eigen::Vector3d(0, 0, 7));
  const std::vector<RigCamera> cameras = {{Pose::Identity(), kFocal}};
  double exact_position = 0, weighed_position = 0, exact_rotation = 0, weighed_rotation = 0;
  const int scenes = 100;
  for (int scene = 0; scene < scenes; ++scene) {
    std::vector<Correspondence> exact, weighed;
    for (int i = 0; i < 150; ++i) {
      const Eigen::Vector3d point(2 * uniform(rng), 1.5 * uniform(rng), depth(rng));
      const double b = baseline(rng);
      const Eigen::Vector3d left(uniform(rng), 0.2 * uniform(rng), 0);
      const std::vector<MapView> views = {{left, kFocal}, {left + Eigen::Vector3d(b, 0, 0), kFocal}};
      const Eigen::Matrix3d covariance = TriangulationCovariance(point, views);
      const Eigen::Matrix3d root = covariance.llt().matrixL();
      const Eigen::Vector3d mapped = point + root * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
      Correspondence c;
      c.normalized = (query * point).hnormalized() + Eigen::Vector2d(gauss(rng), gauss(rng)) / kFocal;
      c.world = mapped;
      exact.push_back(c);
      c.world_covariance = covariance;
      weighed.push_back(c);
    }
    RefineOptions options;
    options.cauchy_scale_px = 1e3;  // least squares: the estimator the test is about
    Pose a = query, b = query;
    ASSERT_TRUE(RefinePose(exact, cameras, options, &a));
    ASSERT_TRUE(RefinePose(weighed, cameras, options, &b));
    exact_position += (a.Center() - query.Center()).norm() / scenes;
    weighed_position += (b.Center() - query.Center()).norm() / scenes;
    exact_rotation += RotationAngleDeg(a.q, query.q) / scenes;
    weighed_rotation += RotationAngleDeg(b.q, query.q) / scenes;
  }
  std::cout << "mean error over " << scenes << " scenes: points exact " << exact_position * 1e3 << " mm / "
            << exact_rotation << " deg, weighed " << weighed_position * 1e3 << " mm / " << weighed_rotation
            << " deg\n";
  EXPECT_LT(weighed_position, 0.8 * exact_position);
  EXPECT_LT(weighed_rotation, 0.8 * exact_rotation);
}

}  // namespace
}  // namespace locforge::localization

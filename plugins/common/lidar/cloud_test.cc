// The map-crispness measure (cloud.h MapPlaneResidual) on clouds with known
// answers: an exact plane, a noisy plane, a doubled wall.
#include "cloud.h"

#include <gtest/gtest.h>

#include <random>

namespace locforge::lidar {
namespace {

Cloud Plane(double z, double noise, uint32_t seed, double offset = 0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, noise > 0 ? noise : 1);
  Cloud c;
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 60; ++j)
      c.points.emplace_back(0.05 * i + offset, 0.05 * j + offset, z + (noise > 0 ? n(rng) : 0));
  return c;
}

TEST(MapPlaneResidual, ExactPlaneIsZeroNoisyPlaneIsItsNoiseDoubledWallIsHalfTheGap) {
  const PlaneResidualStats exact = MapPlaneResidual(Plane(1, 0, 0), 10, 0.5);
  EXPECT_EQ(exact.points, 3600u);
  EXPECT_LT(exact.mean, 1e-6);
  // Gaussian noise sigma: |d| has mean sigma sqrt(2/pi) ~ 0.8 sigma (the fit
  // of 10 neighbours adds a little).
  const PlaneResidualStats noisy = MapPlaneResidual(Plane(1, 0.01, 1), 10, 0.5);
  EXPECT_GT(noisy.mean, 0.006);
  EXPECT_LT(noisy.mean, 0.011);
  // The same wall seen twice, 4 cm apart (interleaved): every point ~2 cm off.
  Cloud doubled = Plane(1, 0, 0);
  const Cloud other = Plane(1.04, 0, 0, 0.025);
  doubled.points.insert(doubled.points.end(), other.points.begin(), other.points.end());
  const PlaneResidualStats blurred = MapPlaneResidual(doubled, 10, 0.5);
  EXPECT_GT(blurred.median, 0.015);
  EXPECT_LT(blurred.median, 0.025);
  // Isolated points are skipped, not counted.
  Cloud sparse;
  sparse.points = {Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(5, 5, 5)};
  const PlaneResidualStats none = MapPlaneResidual(sparse, 10, 0.5);
  EXPECT_EQ(none.points, 0u);
  EXPECT_EQ(none.skipped, 2u);
}

}  // namespace
}  // namespace locforge::lidar

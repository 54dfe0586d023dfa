// The map-crispness measure (cloud.h MapPlaneResidual) on clouds with known
// answers: an exact plane, a noisy plane, a doubled wall.
#include "cloud.h"

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <tuple>

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

TEST(MapPlaneResidual, SameFiguresAtAnyThreadCount) {
  Cloud c = Plane(1, 0.01, 2);
  const Cloud wall = Plane(2, 0.02, 3, 0.01);
  c.points.insert(c.points.end(), wall.points.begin(), wall.points.end());
  c.points.emplace_back(40, 40, 40);  // skipped
  const PlaneResidualStats one = MapPlaneResidual(c, 10, 0.5, 1);
  for (int threads : {2, 3}) {
    const PlaneResidualStats many = MapPlaneResidual(c, 10, 0.5, threads);
    EXPECT_EQ(many.points, one.points);
    EXPECT_EQ(many.skipped, 1u);
    EXPECT_EQ(many.mean, one.mean);
    EXPECT_EQ(many.median, one.median);
    EXPECT_EQ(many.rmse, one.rmse);
    EXPECT_EQ(many.p90, one.p90);
  }
}

// The stride samples the same statistics: on a noisy plane plus a blurred
// wall, every 4th point gives a quarter of the points and figures within 3 %.
TEST(MapPlaneResidual, StrideSamplesTheSameStatistics) {
  Cloud c = Plane(1, 0.01, 2);
  const Cloud wall = Plane(2, 0.02, 3, 0.01);
  c.points.insert(c.points.end(), wall.points.begin(), wall.points.end());
  const PlaneResidualStats all = MapPlaneResidual(c, 10, 0.5, 2);
  const PlaneResidualStats sample = MapPlaneResidual(c, 10, 0.5, 2, 4);
  EXPECT_NEAR(static_cast<double>(sample.points + sample.skipped), (all.points + all.skipped) / 4.0, 1.0);
  EXPECT_NEAR(sample.mean, all.mean, 0.03 * all.mean);
  EXPECT_NEAR(sample.median, all.median, 0.03 * all.median);
  EXPECT_NEAR(sample.rmse, all.rmse, 0.03 * all.rmse);
  EXPECT_NEAR(sample.p90, all.p90, 0.03 * all.p90);
}

// The voxel grid against its definition, written out with an ordered map:
// one centroid per occupied cell, cells in (x, y, z) order, negative
// coordinates included, and cells beyond the packed-key range (+-2^20 cells).
TEST(VoxelDownsample, CentroidPerCellInCellOrder) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-3, 3);
  Cloud c;
  for (int i = 0; i < 20000; ++i) c.points.emplace_back(u(rng), u(rng), u(rng) * 0.3f);
  auto reference = [](const Cloud& cloud, double voxel) {
    std::map<std::tuple<int, int, int>, std::pair<Eigen::Vector3d, int>> cells;
    for (const auto& p : cloud.points) {
      auto& [sum, n] = cells[{static_cast<int>(std::floor(p.x() / voxel)), static_cast<int>(std::floor(p.y() / voxel)),
                              static_cast<int>(std::floor(p.z() / voxel))}];
      if (n == 0) sum.setZero();
      sum += p.cast<double>();
      ++n;
    }
    std::vector<Eigen::Vector3f> out;
    for (const auto& [key, acc] : cells) out.push_back((acc.first / acc.second).cast<float>());
    return out;
  };
  for (double voxel : {0.1, 0.37, 1.0}) {
    const Cloud down = VoxelDownsample(c, voxel);
    const std::vector<Eigen::Vector3f> want = reference(c, voxel);
    ASSERT_EQ(down.points.size(), want.size()) << voxel;
    for (size_t i = 0; i < want.size(); ++i) EXPECT_LT((down.points[i] - want[i]).norm(), 1e-5f) << voxel << " " << i;
  }
  Cloud far = c;
  far.points.emplace_back(2e5f, -2e5f, 1.0f);  // 2e6 cells at 0.1 m: beyond the packed key
  const Cloud down = VoxelDownsample(far, 0.1);
  const std::vector<Eigen::Vector3f> want = reference(far, 0.1);
  ASSERT_EQ(down.points.size(), want.size());
  for (size_t i = 0; i < want.size(); ++i) EXPECT_LT((down.points[i] - want[i]).norm(), 1e-5f) << i;
}

// A cloud given in pieces (a map from keyframes read one at a time): the
// same points as downsampling the concatenation, bit for bit.
TEST(VoxelAccumulator, PiecesGiveVoxelDownsampleOfTheirConcatenation) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-4, 4);
  Cloud whole;
  VoxelAccumulator acc(0.05);
  for (int piece = 0; piece < 7; ++piece) {
    Cloud c;
    for (int i = 0; i < 3000; ++i) c.points.emplace_back(u(rng), u(rng), u(rng) * 0.2f);
    acc.Add(c);
    whole.points.insert(whole.points.end(), c.points.begin(), c.points.end());
  }
  const Cloud want = VoxelDownsample(whole, 0.05);
  const Cloud got = acc.Result();
  ASSERT_GT(want.size(), 1000u);
  ASSERT_LT(want.size(), whole.size());  // cells shared between pieces
  EXPECT_EQ(got.points, want.points);
}

}  // namespace
// Per-point times survive downsampling as each cell's mean (slam/pose_graph
// undistorts keyframes again from them), on both cell paths; no times in,
// none out.
TEST(VoxelDownsample, TimeIsTheCellsMean) {
  Cloud c;
  c.points = {{0.01f, 0.01f, 0.0f}, {0.02f, 0.03f, 0.0f}, {0.5f, 0.5f, 0.0f}};
  c.times = {0.01, 0.03, 0.07};
  const Cloud down = VoxelDownsample(c, 0.1);
  ASSERT_EQ(down.times.size(), 2u);
  EXPECT_DOUBLE_EQ(down.times[0], 0.02);
  EXPECT_DOUBLE_EQ(down.times[1], 0.07);
  Cloud far = c;
  far.points.emplace_back(2e5f, -2e5f, 1.0f);  // the ordered-map path
  far.times.push_back(0.09);
  const Cloud down_far = VoxelDownsample(far, 0.1);
  ASSERT_EQ(down_far.times.size(), 3u);
  EXPECT_DOUBLE_EQ(down_far.times[0], 0.02);  // cells in (x, y, z) order: the far one (x = 2e5) is last
  EXPECT_DOUBLE_EQ(down_far.times[2], 0.09);
  c.times.clear();
  EXPECT_FALSE(VoxelDownsample(c, 0.1).has_times());
}

}  // namespace locforge::lidar

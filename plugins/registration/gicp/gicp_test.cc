// Unit tests of our GICP's parts: KD-tree against brute force, plane
// covariances, robust kernels, and the factor's Jacobian against finite
// differences of its cost.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gicp/factor.h"
#include "gicp/kdtree.h"
#include "gicp/optimizer.h"
#include "gicp/preprocess.h"

namespace locforge::gicp {
namespace {

Points RandomPoints(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-5, 5);
  Points p(n);
  for (auto& x : p) x = {u(rng), u(rng), u(rng)};
  return p;
}

TEST(KdTree, NearestAndKNearestMatchBruteForce) {
  const Points pts = RandomPoints(2000, 1);
  const KdTree tree(pts);
  for (const auto& q : RandomPoints(200, 2)) {
    std::vector<std::pair<double, int>> all;
    for (int i = 0; i < static_cast<int>(pts.size()); ++i) all.push_back({(pts[i] - q).squaredNorm(), i});
    std::sort(all.begin(), all.end());
    int idx;
    double d2;
    ASSERT_TRUE(tree.Nearest(q, 1e9, &idx, &d2));
    EXPECT_EQ(idx, all[0].second);
    EXPECT_DOUBLE_EQ(d2, all[0].first);
    EXPECT_FALSE(tree.Nearest(q, all[0].first * 0.999, &idx, &d2));
    std::vector<int> knn;
    std::vector<double> kd;
    tree.KNearest(q, 20, &knn, &kd);
    ASSERT_EQ(knn.size(), 20u);
    for (int k = 0; k < 20; ++k) EXPECT_DOUBLE_EQ(kd[k], all[k].first) << k;
  }
}

// EstimateCovariances' warm start (each query bounded by the previous one's
// k-th distance plus their gap) returns the neighbours an unbounded search
// returns, so the covariances are bit-identical at any thread count (each
// thread starts its own chain) and equal to those of fresh searches.
TEST(KdTree, WarmStartedKNearestIsExact) {
  Points pts = RandomPoints(3000, 5);
  for (auto& p : pts) p.z() *= 0.02;  // a noisy floor, as LiDAR scans are mostly surfaces
  const KdTree tree(pts);
  std::vector<int> cold, warm;
  std::vector<double> cold_d, warm_d;
  for (int i = 1; i < static_cast<int>(pts.size()); i += 37) {
    const int prev = tree.order()[static_cast<size_t>(i) - 1], cur = tree.order()[i];
    tree.KNearest(pts[prev], 20, &cold, &cold_d);
    const double r = std::sqrt(cold_d.back()) + (pts[cur] - pts[prev]).norm();
    tree.KNearest(pts[cur], 20, &warm, &warm_d, r * r * (1 + 1e-12));
    tree.KNearest(pts[cur], 20, &cold, &cold_d);
    ASSERT_EQ(warm, cold);
    ASSERT_EQ(warm_d, cold_d);
  }
  const Covariances one = EstimateCovariances(pts, tree, 20, 1e-3, 1);
  const Covariances three = EstimateCovariances(pts, tree, 20, 1e-3, 3);
  ASSERT_EQ(one.size(), three.size());
  for (size_t i = 0; i < one.size(); ++i) ASSERT_TRUE(one[i] == three[i]) << i;
}

// Correspondences from the neighbour-list walk (certified, else the tree)
// are those of cold tree searches: the linear systems of an optimizer's
// iterations are bit-identical with and without the lists, and most
// searches of the later iterations are answered by the walk.
TEST(Factor, NeighbourWalkGivesTheTreesCorrespondences) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-4, 4);
  std::normal_distribution<double> noise(0, 0.01);
  PointCloud cloud;  // a floor and two walls, 0.1 m apart on average
  for (int i = 0; i < 6000; ++i) {
    const double a = u(rng), b = u(rng);
    const int face = i % 3;
    const Eigen::Vector3d p = face == 0 ? Eigen::Vector3d(a, b, noise(rng))
                              : face == 1 ? Eigen::Vector3d(a, 4 + noise(rng), 0.4 * (b + 4))
                                          : Eigen::Vector3d(-4 + noise(rng), a, 0.4 * (b + 4));
    cloud.points.push_back(p.cast<float>());
  }
  const PreprocessedCloud target = Preprocess(cloud, PreprocessOptions{0, 20, 1e-3}, 2);
  ASSERT_EQ(target.neighbors.k, 20);
  Points source = target.points;
  for (auto& p : source) p += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  const Covariances source_cov = target.covariances;
  GicpInputs cold{&source, &source_cov, &target.points, &target.covariances, &target.tree};
  GicpInputs warm = cold;
  warm.target_neighbors = &target.neighbors;
  FactorOptions o;
  o.max_correspondence_distance = 0.3;
  o.kernel = RobustKernel::kCauchy;
  o.kernel_width = 0.25;
  std::vector<int> pairs(source.size(), -1);
  for (int it = 0; it < 5; ++it) {  // a converging sequence of poses, as an optimizer's
    const double s = 0.05 / (1 << it);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(s, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(s, -s, 0.2 * s);
    const LinearSystem a = Linearize(cold, T, o, 1);
    const LinearSystem b = Linearize(warm, T, o, 2, &pairs);
    ASSERT_EQ(a.inliers, b.inliers) << it;
    ASSERT_EQ(a.cost, b.cost) << it;
    ASSERT_TRUE(a.H == b.H) << it;
    ASSERT_TRUE(a.b == b.b) << it;
    if (it > 0) EXPECT_GT(b.walked, b.inliers / 2) << it;  // the walk answered most searches
  }
}

TEST(Preprocess, PlaneCovarianceHasTheNormalAsItsSmallAxis) {
  Points plane;
  for (int i = 0; i < 30; ++i)
    for (int j = 0; j < 30; ++j) plane.push_back({0.1 * i, 0.1 * j, 0.3 * 0.1 * i});  // z = 0.3 x
  const KdTree tree(plane);
  const Covariances c = EstimateCovariances(plane, tree, 20, 1e-3, 2);
  const Eigen::Vector3d n = Eigen::Vector3d(-0.3, 0, 1).normalized();
  for (size_t i = 0; i < c.size(); i += 97) {
    EXPECT_NEAR(n.dot(c[i] * n), 1e-3, 1e-9);
    EXPECT_NEAR(c[i].trace(), 2.001, 1e-9);
  }
}

TEST(Preprocess, VoxelGridKeepsOneCentroidPerVoxel) {
  const Points p = {{0.1, 0.1, 0.1}, {0.3, 0.3, 0.3}, {1.5, 0.1, 0.1}, {-0.1, 0.1, 0.1}};
  const Points v = VoxelDownsample(p, 1.0);
  ASSERT_EQ(v.size(), 3u);
  EXPECT_TRUE(v[0].isApprox(Eigen::Vector3d(0.2, 0.2, 0.2)));
  EXPECT_TRUE(v[2].isApprox(Eigen::Vector3d(-0.1, 0.1, 0.1)));
}

TEST(Factor, RobustKernelsWeightAndCost) {
  EXPECT_EQ(RobustWeight(RobustKernel::kNone, 1, 100), 1);
  EXPECT_EQ(RobustWeight(RobustKernel::kHuber, 2, 1), 1);
  EXPECT_DOUBLE_EQ(RobustWeight(RobustKernel::kHuber, 2, 16), 0.5);
  EXPECT_DOUBLE_EQ(RobustWeight(RobustKernel::kCauchy, 2, 4), 0.5);
  // IRLS weight = rho'(e): check by finite differences.
  for (const auto k : {RobustKernel::kHuber, RobustKernel::kCauchy})
    for (const double e : {0.3, 5.0, 40.0}) {
      const double d = (RobustCost(k, 1.5, e + 1e-6) - RobustCost(k, 1.5, e - 1e-6)) / 2e-6;
      EXPECT_NEAR(d, RobustWeight(k, 1.5, e), 1e-5);
    }
}

TEST(Factor, GradientMatchesFiniteDifferences) {
  // Fixed correspondences (a generous rejector, small steps): b = dCost/2dxi.
  const Points target = RandomPoints(300, 3);
  Points source;
  for (const auto& t : target) source.push_back(t + Eigen::Vector3d(0.01, -0.02, 0.015));
  const KdTree tt(target), ts(source);
  const Covariances ct = EstimateCovariances(target, tt, 10, 1e-2, 1);
  const Covariances cs = EstimateCovariances(source, ts, 10, 1e-2, 1);
  const GicpInputs in{&source, &cs, &target, &ct, &tt};
  FactorOptions o;
  o.max_correspondence_distance = 100;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0.002, 0.001, -0.003);
  const LinearSystem s = Linearize(in, T, o, 2);
  for (int k = 0; k < 6; ++k) {
    Vector6d d = Vector6d::Zero();
    d[k] = 1e-7;
    // Covariance rotation R C_s R^T also moves with xi; its effect on the
    // gradient is second order only for the translation part, so check that.
    if (k < 3) continue;
    const double up = Linearize(in, ApplyLeft(d, T), o, 1).cost;
    const double down = Linearize(in, ApplyLeft(-d, T), o, 1).cost;
    EXPECT_NEAR((up - down) / 2e-7, 2 * s.b[k], 1e-3 * std::max(1.0, std::abs(2 * s.b[k]))) << k;
  }
  // Same sums for any thread count.
  const LinearSystem one = Linearize(in, T, o, 1);
  EXPECT_EQ(one.H, s.H);
  EXPECT_EQ(one.cost, s.cost);
}

}  // namespace
}  // namespace locforge::gicp

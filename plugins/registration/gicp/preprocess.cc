#include "preprocess.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <unordered_map>

namespace locforge::gicp {

Points ToPoints(const PointCloud& cloud) {
  Points out(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) out[i] = cloud.points[i].cast<double>();
  return out;
}

Points VoxelDownsample(const Points& points, double voxel_size) {
  if (voxel_size <= 0) return points;
  // 21 bits per axis: +-1M voxels, e.g. +-100 km at 10 cm.
  auto key = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d v = (p / voxel_size).array().floor();
    uint64_t k = 0;
    for (int a = 0; a < 3; ++a)
      k = (k << 21) | (static_cast<uint64_t>(static_cast<int64_t>(v[a]) + (1 << 20)) & 0x1FFFFF);
    return k;
  };
  std::unordered_map<uint64_t, int> voxel_of;
  voxel_of.reserve(points.size());
  Points sum;
  std::vector<int> count;
  for (const Eigen::Vector3d& p : points) {
    if (!p.allFinite()) continue;
    const auto [it, inserted] = voxel_of.emplace(key(p), static_cast<int>(sum.size()));
    if (inserted) {
      sum.push_back(Eigen::Vector3d::Zero());
      count.push_back(0);
    }
    sum[it->second] += p;
    ++count[it->second];
  }
  for (size_t i = 0; i < sum.size(); ++i) sum[i] /= count[i];
  return sum;
}

namespace {

// Plane-regularised covariance of `n` neighbours (one pass: sums of the
// offsets d from the query point and of d d^T; the offsets are small, so the
// cancellation in E[d d^T] - E[d] E[d]^T is harmless).
Eigen::Matrix3d PlaneCovariance(const Points& points, const Eigen::Vector3d& q, const int* idx, int n,
                                double epsilon) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_sq = Eigen::Matrix3d::Zero();
  for (int j = 0; j < n; ++j) {
    const Eigen::Vector3d d = points[idx[j]] - q;
    sum += d;
    sum_sq.noalias() += d * d.transpose();
  }
  const Eigen::Vector3d mean = sum / n;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(sum_sq / n - mean * mean.transpose());
  // Eigenvalues ascending: the first eigenvector is the surface normal, and
  // V diag(epsilon, 1, 1) V^T = I - (1 - epsilon) n n^T.
  const Eigen::Vector3d normal = eig.eigenvectors().col(0);
  return Eigen::Matrix3d::Identity() - (1 - epsilon) * normal * normal.transpose();
}

}  // namespace

Covariances EstimateCovariances(const Points& points, const KdTree& tree, int k, double epsilon,
                                int threads) {
  Covariances out(points.size());
  const std::vector<int>& order = tree.order();
#pragma omp parallel num_threads(threads)
  {
    std::vector<int> idx;
    std::vector<double> d2;
#pragma omp for schedule(static)
    for (int64_t t = 0; t < static_cast<int64_t>(order.size()); ++t) {
      const int i = order[t];  // in tree order: successive queries are neighbours
      tree.KNearest(points[i], k, &idx, &d2);
      out[i] = idx.size() < 3 ? Eigen::Matrix3d::Identity()
                              : PlaneCovariance(points, points[i], idx.data(), static_cast<int>(idx.size()), epsilon);
    }
  }
  return out;
}

PreprocessedCloud Preprocess(const PointCloud& cloud, const PreprocessOptions& o, int threads) {
  Points points = VoxelDownsample(ToPoints(cloud), o.voxel_size);
  KdTree tree(points);
  Covariances covariances = EstimateCovariances(points, tree, o.k_neighbors, o.covariance_epsilon, threads);
  return PreprocessedCloud{std::move(points), std::move(tree), std::move(covariances)};
}

}  // namespace locforge::gicp

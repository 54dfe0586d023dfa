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

Covariances EstimateCovariances(const Points& points, const KdTree& tree, int k, double epsilon,
                                int threads) {
  Covariances out(points.size());
#pragma omp parallel num_threads(threads)
  {
    std::vector<int> idx;
    std::vector<double> d2;
#pragma omp for schedule(static)
    for (int64_t i = 0; i < static_cast<int64_t>(points.size()); ++i) {
      tree.KNearest(points[i], k, &idx, &d2);
      if (idx.size() < 3) {
        out[i] = Eigen::Matrix3d::Identity();
        continue;
      }
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (int j : idx) mean += points[j];
      mean /= static_cast<double>(idx.size());
      Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
      for (int j : idx) c += (points[j] - mean) * (points[j] - mean).transpose();
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
      eig.computeDirect(c / static_cast<double>(idx.size()));
      // Eigenvalues ascending: the first eigenvector is the surface normal.
      const Eigen::Vector3d values(epsilon, 1.0, 1.0);
      out[i] = eig.eigenvectors() * values.asDiagonal() * eig.eigenvectors().transpose();
    }
  }
  return out;
}

}  // namespace locforge::gicp

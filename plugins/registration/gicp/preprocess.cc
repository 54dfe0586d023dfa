#include "preprocess.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

namespace locforge::gicp {

Points ToPoints(const PointCloud& cloud) {
  Points out(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) out[i] = cloud.points[i].cast<double>();
  return out;
}

namespace {

// Open-addressing map from voxel key to voxel index (linear probing, grown
// at half load): no allocation per voxel, unlike std::unordered_map.
class VoxelIndex {
 public:
  // The index of `key`, inserting `next` when absent (then *inserted).
  int FindOrInsert(uint64_t key, int next, bool* inserted) {
    if (2 * (size_ + 1) > keys_.size()) Grow();
    size_t slot = Slot(key);
    for (; keys_[slot] != kEmpty; slot = (slot + 1) & (keys_.size() - 1))
      if (keys_[slot] == key) {
        *inserted = false;
        return values_[slot];
      }
    keys_[slot] = key;
    values_[slot] = next;
    ++size_;
    *inserted = true;
    return next;
  }

 private:
  static constexpr uint64_t kEmpty = ~0ull;  // keys use 63 bits
  size_t Slot(uint64_t key) const { return (key * 0x9E3779B97F4A7C15ull) >> (64 - bits_); }
  void Grow() {
    std::vector<uint64_t> keys(size_t{1} << ++bits_, kEmpty);
    std::vector<int> values(keys.size());
    keys.swap(keys_);
    values.swap(values_);
    for (size_t i = 0; i < keys.size(); ++i) {
      if (keys[i] == kEmpty) continue;
      size_t slot = Slot(keys[i]);
      while (keys_[slot] != kEmpty) slot = (slot + 1) & (keys_.size() - 1);
      keys_[slot] = keys[i];
      values_[slot] = values[i];
    }
  }
  int bits_ = 9;
  size_t size_ = 0;
  std::vector<uint64_t> keys_ = std::vector<uint64_t>(size_t{1} << 9, kEmpty);
  std::vector<int> values_ = std::vector<int>(size_t{1} << 9);
};

template <typename Point>
Points VoxelCentroids(const std::vector<Point>& points, double voxel_size) {
  // 21 bits per axis: +-1M voxels, e.g. +-100 km at 10 cm.
  auto key = [&](const Eigen::Vector3d& p) {
    uint64_t k = 0;
    for (int a = 0; a < 3; ++a) {
      const double s = p[a] / voxel_size;
      int64_t v = static_cast<int64_t>(s);  // floor(s), without a libm call
      v -= s < static_cast<double>(v);
      k = (k << 21) | (static_cast<uint64_t>(v + (1 << 20)) & 0x1FFFFF);
    }
    return k;
  };
  VoxelIndex voxel_of;
  Points sum;
  std::vector<int> count;
  for (const Point& point : points) {
    const Eigen::Vector3d p = point.template cast<double>();
    if (!p.allFinite()) continue;
    bool inserted;
    const int v = voxel_of.FindOrInsert(key(p), static_cast<int>(sum.size()), &inserted);
    if (inserted) {
      sum.push_back(Eigen::Vector3d::Zero());
      count.push_back(0);
    }
    sum[v] += p;
    ++count[v];
  }
  for (size_t i = 0; i < sum.size(); ++i) sum[i] /= count[i];
  return sum;
}

}  // namespace

Points VoxelDownsample(const Points& points, double voxel_size) {
  return voxel_size > 0 ? VoxelCentroids(points, voxel_size) : points;
}

Points VoxelDownsample(const PointCloud& cloud, double voxel_size) {
  return voxel_size > 0 ? VoxelCentroids(cloud.points, voxel_size) : ToPoints(cloud);
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
                                int threads, NeighborGraph* graph) {
  Covariances out(points.size());
  const int listed = std::max(0, std::min<int>(k, static_cast<int>(points.size())));  // neighbours per point
  if (graph) {
    graph->k = listed;
    graph->ids.assign(points.size() * static_cast<size_t>(listed), -1);
    graph->radius.assign(points.size(), std::numeric_limits<double>::infinity());
  }
  const std::vector<int>& order = tree.order();
#pragma omp parallel num_threads(threads)
  {
    std::vector<int> idx;
    std::vector<double> d2;
    int previous = -1;  // the last query of this thread and the distance to its k-th neighbour
    double previous_radius = 0;
#pragma omp for schedule(static)
    for (int64_t t = 0; t < static_cast<int64_t>(order.size()); ++t) {
      const int i = order[t];  // in tree order: successive queries are neighbours
      // Warm start (exact): the previous query's k neighbours lie within
      // previous_radius + |q - previous| of q (triangle inequality), so q's k
      // nearest do too; the search prunes by that bound from its first step.
      double bound = std::numeric_limits<double>::infinity();
      if (previous >= 0) {
        const double r = previous_radius + (points[i] - points[previous]).norm();
        bound = r * r * (1 + 1e-12) + 1e-300;  // never below the k-th distance by rounding
      }
      tree.KNearest(points[i], k, &idx, &d2, bound);
      if (static_cast<int>(idx.size()) < listed) tree.KNearest(points[i], k, &idx, &d2);  // cannot happen; cheap insurance
      const bool complete = listed > 0 && static_cast<int>(idx.size()) == listed;
      if (graph && complete) {
        std::copy(idx.begin(), idx.end(), graph->ids.begin() + static_cast<int64_t>(i) * listed);
        // Fewer points than k: every point is listed, so nothing lies beyond.
        if (listed == k) graph->radius[i] = std::sqrt(d2.back());
      }
      if (complete) {
        previous = i;
        previous_radius = std::sqrt(d2.back());
      } else {
        previous = -1;
      }
      out[i] = idx.size() < 3 ? Eigen::Matrix3d::Identity()
                              : PlaneCovariance(points, points[i], idx.data(), static_cast<int>(idx.size()), epsilon);
    }
  }
  return out;
}

PreprocessedCloud Preprocess(const PointCloud& cloud, const PreprocessOptions& o, int threads) {
  Points points = VoxelDownsample(cloud, o.voxel_size);
  KdTree tree(points);
  NeighborGraph neighbors;
  Covariances covariances =
      EstimateCovariances(points, tree, o.k_neighbors, o.covariance_epsilon, threads, &neighbors);
  return PreprocessedCloud{std::move(points), std::move(tree), std::move(covariances), std::move(neighbors)};
}

}  // namespace locforge::gicp

#include "cloud.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cstdlib>
#include <cmath>
#include <limits>
#include <map>
#include <tuple>
#include <unordered_map>

namespace locforge::lidar {

Cloud ReadScan(const fs::path& path) {
  Cloud cloud = ReadPointCloud(path);
  size_t kept = 0;
  for (size_t k = 0; k < cloud.points.size(); ++k) {
    if (!cloud.points[k].allFinite()) continue;
    cloud.points[kept] = cloud.points[k];
    if (!cloud.times.empty()) cloud.times[kept] = cloud.times[k];
    if (!cloud.normals.empty()) cloud.normals[kept] = cloud.normals[k];
    ++kept;
  }
  cloud.points.resize(kept);
  if (!cloud.times.empty()) cloud.times.resize(kept);
  if (!cloud.normals.empty()) cloud.normals.resize(kept);
  return cloud;
}

namespace {
// The reference: an ordered map of cells (used when a cell index leaves the
// 21-bit range of the packed key below).
Cloud VoxelDownsampleOrdered(const Cloud& cloud, double voxel) {
  struct Acc { Eigen::Vector3d sum = Eigen::Vector3d::Zero(); double time = 0; int n = 0; };
  std::map<std::tuple<int, int, int>, Acc> grid;
  const double inv = 1.0 / voxel;
  const bool timed = cloud.has_times();
  for (size_t i = 0; i < cloud.points.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    auto& a = grid[{static_cast<int>(std::floor(p.x() * inv)), static_cast<int>(std::floor(p.y() * inv)),
                    static_cast<int>(std::floor(p.z() * inv))}];
    a.sum += p.cast<double>();
    if (timed) a.time += cloud.times[i];
    ++a.n;
  }
  Cloud out;
  out.points.reserve(grid.size());
  for (const auto& [key, a] : grid) {
    out.points.push_back((a.sum / a.n).cast<float>());
    if (timed) out.times.push_back(a.time / a.n);
  }
  return out;
}
}  // namespace

Cloud VoxelDownsample(const Cloud& cloud, double voxel) {
  // Cells found by hashing, then emitted in (x, y, z) order: the same points,
  // the same sums in the same order, as the ordered map (so outputs stay
  // byte-identical), without a tree walk per point. The packed key (21 bits per
  // axis, offset by 2^20) orders like the (x, y, z) tuple.
  constexpr int64_t kHalf = int64_t{1} << 20;
  const double inv = 1.0 / voxel;
  std::vector<uint64_t> keys(cloud.points.size());
  for (size_t i = 0; i < cloud.points.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    uint64_t key = 0;
    for (int a = 0; a < 3; ++a) {
      const double c = std::floor(p[a] * inv);
      if (!(c >= -kHalf && c < kHalf)) return VoxelDownsampleOrdered(cloud, voxel);  // also NaN
      key = (key << 21) | static_cast<uint64_t>(static_cast<int64_t>(c) + kHalf);
    }
    keys[i] = key;
  }
  // Room for a cell per point: a scan at 0.1 m keeps half its points, so a
  // smaller table rehashes several times per scan.
  std::unordered_map<uint64_t, uint32_t> slot_of;
  slot_of.reserve(cloud.points.size() + 16);
  std::vector<Eigen::Vector3d> sum;
  std::vector<double> time_sum;
  std::vector<int> count;
  std::vector<uint64_t> slot_key;
  sum.reserve(cloud.points.size());
  count.reserve(cloud.points.size());
  slot_key.reserve(cloud.points.size());
  const bool timed = cloud.has_times();
  if (timed) time_sum.reserve(cloud.points.size());
  for (size_t i = 0; i < keys.size(); ++i) {
    const auto [it, inserted] = slot_of.try_emplace(keys[i], static_cast<uint32_t>(sum.size()));
    if (inserted) {
      sum.push_back(Eigen::Vector3d::Zero());
      if (timed) time_sum.push_back(0);
      count.push_back(0);
      slot_key.push_back(keys[i]);
    }
    sum[it->second] += cloud.points[i].cast<double>();
    if (timed) time_sum[it->second] += cloud.times[i];
    ++count[it->second];
  }
  // Cells in key order: the keys themselves sorted with their slots (one
  // contiguous array, no indirection in the comparisons; keys are unique).
  std::vector<std::pair<uint64_t, uint32_t>> cells(sum.size());
  for (uint32_t s = 0; s < cells.size(); ++s) cells[s] = {slot_key[s], s};
  std::sort(cells.begin(), cells.end());
  Cloud out;
  out.points.reserve(cells.size());
  for (const auto& [key, s] : cells) {
    out.points.push_back((sum[s] / count[s]).cast<float>());
    if (timed) out.times.push_back(time_sum[s] / count[s]);
  }
  return out;
}

size_t VoxelAccumulator::KeyHash::operator()(const std::tuple<int, int, int>& k) const {
  const uint64_t h = (static_cast<uint64_t>(static_cast<uint32_t>(std::get<0>(k))) * 0x9E3779B97F4A7C15ull) ^
                     (static_cast<uint64_t>(static_cast<uint32_t>(std::get<1>(k))) * 0xC2B2AE3D27D4EB4Full) ^
                     (static_cast<uint64_t>(static_cast<uint32_t>(std::get<2>(k))) * 0x165667B19E3779F9ull);
  return static_cast<size_t>(h ^ (h >> 29));
}

void VoxelAccumulator::Add(const Cloud& piece) {
  for (const Eigen::Vector3f& p : piece.points) {
    Cell& c = cells_[{static_cast<int>(std::floor(p.x() * inv_)), static_cast<int>(std::floor(p.y() * inv_)),
                      static_cast<int>(std::floor(p.z() * inv_))}];
    c.sum += p.cast<double>();
    ++c.n;
  }
}

Cloud VoxelAccumulator::Result() const {
  // In (x, y, z) cell order, as VoxelDownsample emits them.
  std::vector<std::pair<std::tuple<int, int, int>, const Cell*>> sorted;
  sorted.reserve(cells_.size());
  for (const auto& [key, cell] : cells_) sorted.emplace_back(key, &cell);
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  Cloud out;
  out.points.reserve(sorted.size());
  for (const auto& [key, cell] : sorted) out.points.push_back((cell->sum / cell->n).cast<float>());
  return out;
}

void Transform(const Pose& T, Cloud* cloud) {
  const Eigen::Matrix3f R = T.R().cast<float>();
  const Eigen::Vector3f t = T.t.cast<float>();
  for (auto& p : cloud->points) p = R * p + t;
}

namespace {
// Hash of a grid cell (three 21-bit signed coordinates).
uint64_t CellKey(int x, int y, int z) {
  auto u = [](int v) { return static_cast<uint64_t>(static_cast<uint32_t>(v) & 0x1fffff); };
  return (u(x) << 42) | (u(y) << 21) | u(z);
}
// Neighbours by a grid of cells of side h = radius / 4, searched in shells
// of cells around the point's (Chebyshev ring s = 0, 1, ..., 4): a point in
// a ring beyond s is at least s h away, so the search stops once k
// neighbours are within s h (the same k nearest as a search of the whole
// radius, at a fraction of the distance tests in a dense map).
struct ShellGrid {
  static constexpr int kRings = 4;
  ShellGrid(const Cloud& map, double radius) : h(radius / kRings), inv(1.0 / h), r2(radius * radius) {
    for (size_t i = 0; i < map.size(); ++i) {
      const Eigen::Vector3i c = Cell(map.points[i]);
      cells[CellKey(c.x(), c.y(), c.z())].push_back(static_cast<uint32_t>(i));
    }
  }
  Eigen::Vector3i Cell(const Eigen::Vector3f& p) const {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() * inv)), static_cast<int>(std::floor(p.y() * inv)),
                           static_cast<int>(std::floor(p.z() * inv)));
  }
  // The points of ring s around cell c within the radius of point i (into near).
  void AddRing(const Cloud& map, int64_t i, const Eigen::Vector3i& c, int s,
               std::vector<std::pair<float, uint32_t>>* near) const {
    const Eigen::Vector3f& p = map.points[i];
    for (int dx = -s; dx <= s; ++dx)
      for (int dy = -s; dy <= s; ++dy)
        for (int dz = -s; dz <= s; ++dz) {
          if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != s) continue;
          const auto it = cells.find(CellKey(c.x() + dx, c.y() + dy, c.z() + dz));
          if (it == cells.end()) continue;
          for (uint32_t j : it->second) {
            if (static_cast<int64_t>(j) == i) continue;
            const float d2 = (map.points[j] - p).squaredNorm();
            if (d2 <= r2) near->emplace_back(d2, j);
          }
        }
  }
  // Point i's neighbours within the radius, rings out until the k nearest are certain.
  void Neighbours(const Cloud& map, int64_t i, int k, std::vector<std::pair<float, uint32_t>>* near) const {
    const Eigen::Vector3i c = Cell(map.points[i]);
    near->clear();
    for (int s = 0; s <= kRings; ++s) {
      AddRing(map, i, c, s, near);
      if (static_cast<int>(near->size()) >= k) {
        std::nth_element(near->begin(), near->begin() + (k - 1), near->end());
        if ((*near)[k - 1].first <= (s * h) * (s * h)) break;
      }
    }
  }

  const double h, inv, r2;
  std::unordered_map<uint64_t, std::vector<uint32_t>> cells;
};

// Distance of p to the plane of its k nearest neighbours (normal: the
// covariance's eigenvector of the smallest eigenvalue); NaN with fewer than k.
double PlaneResidualOf(const Cloud& map, const Eigen::Vector3f& p, std::vector<std::pair<float, uint32_t>>& near,
                       int k) {
  if (static_cast<int>(near.size()) < k) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(near.begin(), near.begin() + (k - 1), near.end());
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int n = 0; n < k; ++n) mean += map.points[near[n].second].cast<double>();
  mean /= k;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int n = 0; n < k; ++n) {
    const Eigen::Vector3d d = map.points[near[n].second].cast<double>() - mean;
    cov += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  const Eigen::Vector3d normal = eig.eigenvectors().col(0);  // smallest eigenvalue
  return std::abs(normal.dot(p.cast<double>() - mean));
}

// The statistics of every stride-th point's residual, in point order.
PlaneResidualStats SummarizeResiduals(const std::vector<double>& residual, int stride) {
  PlaneResidualStats out;
  std::vector<double> residuals;
  residuals.reserve(residual.size() / stride + 1);
  for (size_t i = 0; i < residual.size(); i += stride) {
    if (std::isnan(residual[i])) ++out.skipped;
    else residuals.push_back(residual[i]);
  }
  out.points = residuals.size();
  if (residuals.empty()) return out;
  double sum = 0, sq = 0;
  for (double r : residuals) {
    sum += r;
    sq += r * r;
  }
  out.mean = sum / residuals.size();
  out.rmse = std::sqrt(sq / residuals.size());
  std::sort(residuals.begin(), residuals.end());
  out.median = residuals[residuals.size() / 2];
  out.p90 = residuals[std::min(residuals.size() - 1, residuals.size() * 9 / 10)];
  return out;
}

}  // namespace

PlaneResidualStats MapPlaneResidual(const Cloud& map, int k, double radius, int threads, int stride) {
  stride = std::max(1, stride);
  const ShellGrid grid(map, radius);
  // One residual per point (NaN: too few neighbours), computed in parallel;
  // the statistics then read them in point order (same figures at any thread count).
  std::vector<double> residual(map.size(), std::numeric_limits<double>::quiet_NaN());
#pragma omp parallel num_threads(std::max(1, threads))
  {
    std::vector<std::pair<float, uint32_t>> near;
#pragma omp for schedule(dynamic, 256)
    for (int64_t i = 0; i < static_cast<int64_t>(map.size()); i += stride) {
      grid.Neighbours(map, i, k, &near);
      residual[i] = PlaneResidualOf(map, map.points[i], near, k);
    }
  }
  return SummarizeResiduals(residual, stride);
}

}  // namespace locforge::lidar

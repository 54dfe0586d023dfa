#include "cloud.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cstdlib>
#include <cmath>
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

Cloud VoxelDownsample(const Cloud& cloud, double voxel) {
  struct Acc { Eigen::Vector3d sum = Eigen::Vector3d::Zero(); int n = 0; };
  std::map<std::tuple<int, int, int>, Acc> grid;  // ordered: deterministic output
  const double inv = 1.0 / voxel;
  for (const auto& p : cloud.points) {
    auto& a = grid[{static_cast<int>(std::floor(p.x() * inv)), static_cast<int>(std::floor(p.y() * inv)),
                    static_cast<int>(std::floor(p.z() * inv))}];
    a.sum += p.cast<double>();
    ++a.n;
  }
  Cloud out;
  out.points.reserve(grid.size());
  for (const auto& [key, a] : grid) out.points.push_back((a.sum / a.n).cast<float>());
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
}  // namespace

PlaneResidualStats MapPlaneResidual(const Cloud& map, int k, double radius) {
  // Neighbours by a grid of cells of side h = radius / 4, searched in shells
  // of cells around the point's (Chebyshev ring s = 0, 1, ..., 4): a point in
  // a ring beyond s is at least s h away, so the search stops once k
  // neighbours are within s h (the same k nearest as a search of the whole
  // radius, at a fraction of the distance tests in a dense map).
  constexpr int kRings = 4;
  const double h = radius / kRings;
  const double inv = 1.0 / h;
  auto cell = [&](const Eigen::Vector3f& p) {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() * inv)), static_cast<int>(std::floor(p.y() * inv)),
                           static_cast<int>(std::floor(p.z() * inv)));
  };
  std::unordered_map<uint64_t, std::vector<uint32_t>> grid;
  for (size_t i = 0; i < map.size(); ++i) {
    const Eigen::Vector3i c = cell(map.points[i]);
    grid[CellKey(c.x(), c.y(), c.z())].push_back(static_cast<uint32_t>(i));
  }
  const double r2 = radius * radius;
  std::vector<double> residuals;
  residuals.reserve(map.size());
  PlaneResidualStats out;
  std::vector<std::pair<float, uint32_t>> near;
  for (size_t i = 0; i < map.size(); ++i) {
    const Eigen::Vector3f& p = map.points[i];
    const Eigen::Vector3i c = cell(p);
    near.clear();
    for (int s = 0; s <= kRings; ++s) {
      for (int dx = -s; dx <= s; ++dx)
        for (int dy = -s; dy <= s; ++dy)
          for (int dz = -s; dz <= s; ++dz) {
            if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != s) continue;
            const auto it = grid.find(CellKey(c.x() + dx, c.y() + dy, c.z() + dz));
            if (it == grid.end()) continue;
            for (uint32_t j : it->second) {
              if (j == i) continue;
              const float d2 = (map.points[j] - p).squaredNorm();
              if (d2 <= r2) near.emplace_back(d2, j);
            }
          }
      if (static_cast<int>(near.size()) >= k) {
        std::nth_element(near.begin(), near.begin() + (k - 1), near.end());
        if (near[k - 1].first <= (s * h) * (s * h)) break;
      }
    }
    if (static_cast<int>(near.size()) < k) {
      ++out.skipped;
      continue;
    }
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
    residuals.push_back(std::abs(normal.dot(p.cast<double>() - mean)));
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

}  // namespace locforge::lidar

#include "depth_projection.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "locforge/error.h"

namespace locforge::depth {

bool DepthProjectionOptions::Check(std::string* why) const {
  if (!(point_radius_m > 0)) return *why = "point_radius_m must be > 0", false;
  if (!(min_depth_m > 0) || !(max_depth_m > min_depth_m)) return *why = "need 0 < min_depth_m < max_depth_m", false;
  if (max_splat_radius_px < 0) return *why = "max_splat_radius_px must be >= 0", false;
  if (!(blend_depth_m >= 0)) return *why = "blend_depth_m must be >= 0", false;
  return true;
}

MapIndex::MapIndex(std::vector<Eigen::Vector3f> points, double cell_m) : cell_m_(cell_m) {
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const auto& p : points) {
    lo = lo.cwiseMin(p.head<2>().cast<double>());
    hi = hi.cwiseMax(p.head<2>().cast<double>());
  }
  if (points.empty()) lo = hi = Eigen::Vector2d::Zero();
  origin_ = lo;
  nx_ = Cell(hi.x() - lo.x()) + 1;
  ny_ = Cell(hi.y() - lo.y()) + 1;
  std::vector<uint32_t> cell_of(points.size());
  start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (size_t i = 0; i < points.size(); ++i) {
    const int cx = std::clamp(Cell(points[i].x() - origin_.x()), 0, nx_ - 1);
    const int cy = std::clamp(Cell(points[i].y() - origin_.y()), 0, ny_ - 1);
    cell_of[i] = static_cast<uint32_t>(cy * nx_ + cx);
    ++start_[cell_of[i] + 1];
  }
  for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
  points_.resize(points.size());
  std::vector<uint32_t> next(start_.begin(), start_.end() - 1);
  for (size_t i = 0; i < points.size(); ++i) points_[next[cell_of[i]]++] = points[i];
}

DepthMap ProjectMap(const MapIndex& map, const Camera& camera, const Pose& T_camera_world,
                    const DepthProjectionOptions& o) {
  DepthMap out;
  out.width = camera.width;
  out.height = camera.height;
  const size_t n = static_cast<size_t>(out.width) * out.height;
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<float> nearest(n, inf);  // pass 1: the visible surface (z-buffer of the discs)
  std::vector<float> sum_wz(n, 0.f), sum_w(n, 0.f), max_w(n, 0.f);  // pass 2: its depth, blended
  const Eigen::Matrix3d R = T_camera_world.R();
  const Eigen::Vector3d t = T_camera_world.t;
  const Eigen::Vector3d centre = -(R.transpose() * t);  // camera centre in the world
  const double f = 0.5 * (camera.fx() + camera.fy());
  // Calls fn(pixel index, squared distance (px^2), disc radius (px), z) over the disc of each point in range.
  auto splat = [&](auto&& fn) {
    map.ForEachNear(centre, o.max_depth_m, [&](const Eigen::Vector3f& X) {
      const Eigen::Vector3d p = R * X.cast<double>() + t;
      if (p.z() < o.min_depth_m || p.z() > o.max_depth_m) return;
      const Eigen::Vector2d uv = camera.Project(p);
      const double rf = std::max(0.5, std::min<double>(o.max_splat_radius_px, o.point_radius_m * f / p.z()));
      const int r = static_cast<int>(std::ceil(rf));
      const int u = static_cast<int>(std::floor(uv.x())), v = static_cast<int>(std::floor(uv.y()));
      if (u + r < 0 || v + r < 0 || u - r >= out.width || v - r >= out.height) return;
      const float z = static_cast<float>(p.z());
      for (int y = std::max(0, v - r); y <= std::min(out.height - 1, v + r); ++y)
        for (int x = std::max(0, u - r); x <= std::min(out.width - 1, u + r); ++x) {
          const double dx = x + 0.5 - uv.x(), dy = y + 0.5 - uv.y();
          const double d2 = dx * dx + dy * dy;
          if (d2 <= rf * rf || (x == u && y == v)) fn(static_cast<size_t>(y) * out.width + x, d2, rf, z);
        }
    });
  };
  splat([&](size_t i, double, double, float z) { nearest[i] = std::min(nearest[i], z); });
  // Every disc of the visible surface (within blend_depth_m of the nearest)
  // votes with a Gaussian weight of its centre's distance (sigma 0.3 x its
  // radius, at least 0.7 px): a disc carries its centre's depth only, and on
  // a slanted surface (a floor seen at grazing angle) its far rim is wrong by
  // the slope times the radius; the centres nearest the pixel are right.
  splat([&](size_t i, double d2, double rf, float z) {
    if (z > nearest[i] + o.blend_depth_m) return;
    const double sigma = std::max(0.7, 0.3 * rf);
    const float w = static_cast<float>(std::exp(-d2 / (2 * sigma * sigma))) + 1e-12f;
    sum_wz[i] += w * z;
    sum_w[i] += w;
    max_w[i] = std::max(max_w[i], w);
  });
  // A pixel whose nearest visible centre is over 2.5 sigma away lies on the
  // rim of a surface's discs: beside a silhouette, the discs of the nearer
  // object would give it the object's depth. Such pixels get none.
  const float rim = static_cast<float>(std::exp(-2.5 * 2.5 / 2));
  out.z.assign(n, 0.f);
  for (size_t i = 0; i < n; ++i)
    if (sum_w[i] > 0 && max_w[i] >= rim) out.z[i] = sum_wz[i] / sum_w[i];
  return out;
}

void AccumulateDepthErrors(const DepthMap& estimate, const DepthMap& reference, const std::vector<uint8_t>* keep,
                           double tolerance_m, DepthErrors* e) {
  if (estimate.width != reference.width || estimate.height != reference.height)
    throw Error("depth maps of different sizes");
  for (size_t i = 0; i < reference.z.size(); ++i) {
    if (keep && !(*keep)[i]) continue;
    if (!(reference.z[i] > 0)) continue;
    ++e->reference_valid;
    if (!(estimate.z[i] > 0)) continue;
    ++e->compared;
    const double d = estimate.z[i] - reference.z[i];
    e->nearer += d < -tolerance_m;
    e->farther += d > tolerance_m;
    e->Add(std::abs(d));
  }
}

void DepthErrors::Add(double abs_error_m) {
  const double bin = abs_error_m / kBinM;
  ++histogram[bin >= kBins || !std::isfinite(bin) ? kBins : static_cast<size_t>(bin)];
}

void DepthErrors::Merge(const DepthErrors& other) {
  compared += other.compared;
  reference_valid += other.reference_valid;
  nearer += other.nearer;
  farther += other.farther;
  for (size_t i = 0; i < histogram.size(); ++i) histogram[i] += other.histogram[i];
}

double DepthErrors::Quantile(double q) const {
  uint64_t total = 0;
  for (uint64_t c : histogram) total += c;
  if (!total) return std::numeric_limits<double>::quiet_NaN();
  const double target = q * static_cast<double>(total);
  uint64_t seen = 0;
  for (size_t i = 0; i < histogram.size(); ++i) {
    seen += histogram[i];
    if (static_cast<double>(seen) >= target && histogram[i])
      return i == kBins ? std::numeric_limits<double>::infinity() : (i + 1) * kBinM;
  }
  return std::numeric_limits<double>::infinity();
}

double DepthErrors::FractionWithin(double m) const {
  uint64_t total = 0, within = 0;
  const size_t last = static_cast<size_t>(std::min<double>(kBins, m / kBinM));
  for (size_t i = 0; i < histogram.size(); ++i) {
    total += histogram[i];
    if (i < last) within += histogram[i];
  }
  return total ? static_cast<double>(within) / total : 0;
}

std::string EncodeDepth(const DepthMap& depth) {
  static_assert(sizeof(float) == 4, "kapture depth maps are float32");
  return std::string(reinterpret_cast<const char*>(depth.z.data()), depth.z.size() * sizeof(float));
}

DepthMap DecodeDepth(const std::string& bytes, int width, int height, const std::string& file) {
  const size_t expected = static_cast<size_t>(width) * height * sizeof(float);
  if (bytes.size() != expected)
    throw InputError(file, 0, "depth", std::to_string(bytes.size()) + " bytes, expected " + std::to_string(width) +
                                           " x " + std::to_string(height) + " float32 = " + std::to_string(expected));
  DepthMap d;
  d.width = width;
  d.height = height;
  d.z.resize(static_cast<size_t>(width) * height);
  std::memcpy(d.z.data(), bytes.data(), expected);
  return d;
}

}  // namespace locforge::depth

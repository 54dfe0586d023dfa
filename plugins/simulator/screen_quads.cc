#include "screen_quads.h"

#include <algorithm>
#include <cmath>

namespace locforge::sim {
namespace {

// Quads padded by this much, in metres. A quad hit computed by InsideQuad
// lies within ~1e-12 m of the quad, so inside this padding, whatever the
// rounding of its distance t.
constexpr double kPad = 1e-6;
// Quads closer to the image plane than this (camera z, metres) project too
// unstably to bound: they go into every tile.
constexpr double kNearZ = 0.01;

}  // namespace

ScreenQuads::ScreenQuads(const std::vector<Quad>& quads, const PinholeCamera& camera, const Pose& T_world_camera,
                         int row_begin, int row_end)
    : quads_(quads) {
  row_end = std::min(row_end, camera.height);
  tiles_x_ = (camera.width + kTile - 1) / kTile;
  tile_y0_ = row_begin / kTile;
  tiles_y_ = std::max(0, (row_end + kTile - 1) / kTile - tile_y0_);
  if (tiles_x_ == 0 || tiles_y_ == 0) return;
  const Eigen::Matrix3d R_camera_world = T_world_camera.R().transpose();
  const Eigen::Vector3d& o = T_world_camera.t;

  struct Span {
    int quad, tx0, tx1, ty0, ty1;
    double min_distance;
  };
  std::vector<Span> spans;
  for (int i = 0; i < static_cast<int>(quads.size()); ++i) {
    const Quad& q = quads[i];
    const Eigen::Vector3d corners[4] = {q.origin, q.origin + q.u_edge, q.origin + q.v_edge,
                                        q.origin + q.u_edge + q.v_edge};
    Eigen::Vector3d lo = corners[0], hi = corners[0];
    double z_min = std::numeric_limits<double>::infinity(), z_max = -z_min;
    Eigen::Vector2d p_min = Eigen::Vector2d::Constant(z_min), p_max = -p_min;
    Eigen::Vector3d in_camera[4];
    for (int k = 0; k < 4; ++k) {
      lo = lo.cwiseMin(corners[k]);
      hi = hi.cwiseMax(corners[k]);
      in_camera[k] = R_camera_world * (corners[k] - o);
      z_min = std::min(z_min, in_camera[k].z());
      z_max = std::max(z_max, in_camera[k].z());
    }
    // Pixel rays point forward (camera z > 0): a quad wholly behind is never hit.
    if (z_max < -kPad) continue;
    Span s{i, 0, tiles_x_ - 1, tile_y0_, tile_y0_ + tiles_y_ - 1, 0};
    if (z_min >= kNearZ) {
      // In front: its projection is the convex hull of its projected corners.
      for (const Eigen::Vector3d& c : in_camera) {
        const Eigen::Vector2d p = camera.Project(c);
        p_min = p_min.cwiseMin(p);
        p_max = p_max.cwiseMax(p);
      }
      // Pixel (x, y) has its centre at (x + 0.5, y + 0.5).
      const double x0 = std::ceil(p_min.x() - kMarginPx - 0.5), x1 = std::floor(p_max.x() + kMarginPx - 0.5);
      const double y0 = std::ceil(p_min.y() - kMarginPx - 0.5), y1 = std::floor(p_max.y() + kMarginPx - 0.5);
      if (x1 < 0 || y1 < row_begin || x0 > camera.width - 1 || y0 > row_end - 1 || x0 > x1 || y0 > y1) continue;
      s.tx0 = static_cast<int>(std::max(0.0, x0)) / kTile;
      s.tx1 = static_cast<int>(std::min<double>(camera.width - 1, x1)) / kTile;
      s.ty0 = static_cast<int>(std::max<double>(row_begin, y0)) / kTile;
      s.ty1 = static_cast<int>(std::min<double>(row_end - 1, y1)) / kTile;
    }
    // Any hit lies in the padded box: no nearer than the box is to the camera.
    lo.array() -= kPad;
    hi.array() += kPad;
    const Eigen::Vector3d gap = (lo - o).cwiseMax(o - hi).cwiseMax(0.0);
    s.min_distance = gap.norm() * (1 - 1e-9);
    spans.push_back(s);
  }

  // Tiles' lists, nearest first (then by quad index, for a stable order).
  std::sort(spans.begin(), spans.end(), [](const Span& a, const Span& b) {
    return a.min_distance < b.min_distance || (a.min_distance == b.min_distance && a.quad < b.quad);
  });
  tile_start_.assign(static_cast<size_t>(tiles_x_) * tiles_y_ + 1, 0);
  const auto tile = [&](int tx, int ty) { return static_cast<size_t>(ty - tile_y0_) * tiles_x_ + tx; };
  for (const Span& s : spans)
    for (int ty = s.ty0; ty <= s.ty1; ++ty)
      for (int tx = s.tx0; tx <= s.tx1; ++tx) ++tile_start_[tile(tx, ty) + 1];
  for (size_t i = 1; i < tile_start_.size(); ++i) tile_start_[i] += tile_start_[i - 1];
  entries_.resize(tile_start_.back());
  std::vector<int> fill(tile_start_.begin(), tile_start_.end() - 1);
  for (const Span& s : spans)
    for (int ty = s.ty0; ty <= s.ty1; ++ty)
      for (int tx = s.tx0; tx <= s.tx1; ++tx) entries_[fill[tile(tx, ty)]++] = {s.min_distance, s.quad};
}

NearestQuadSearch ScreenQuads::Nearest(int x, int y, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                       double t_min) const {
  NearestQuadSearch search;
  const size_t t = static_cast<size_t>(y / kTile - tile_y0_) * tiles_x_ + x / kTile;
  for (int i = tile_start_[t]; i < tile_start_[t + 1]; ++i) {
    const Entry& e = entries_[i];
    if (e.min_distance > search.t) break;  // this quad and the rest are farther
    search.Test(quads_[e.quad], e.quad, o, d, t_min);
  }
  return search;
}

double ScreenQuads::MeanQuadsPerTile() const {
  return tile_start_.empty() ? 0 : double(entries_.size()) / (tile_start_.size() - 1);
}

}  // namespace locforge::sim

#include "screen_tiles.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace locforge::sim {
namespace {

// Items are padded by this much, in metres: a computed ray-quad or
// ray-cylinder hit lies within ~1e-12 m of the surface, so inside.
constexpr double kPad = 1e-6;
// Items closer to the image plane than this (camera z, metres) project too
// unstably to bound: they go into every tile.
constexpr double kNearZ = 0.01;

}  // namespace

ScreenTiles::ScreenTiles(const PinholeCamera& camera, const Pose& T_world_camera, int row_begin, int row_end)
    : camera_(camera), R_camera_world_(T_world_camera.R().transpose()), origin_(T_world_camera.t) {
  row_begin_ = std::max(0, row_begin);
  row_end_ = std::min(row_end, camera.height);
  tiles_x_ = (camera.width + kTile - 1) / kTile;
  tile_y0_ = row_begin_ / kTile;
  tiles_y_ = std::max(0, (row_end_ + kTile - 1) / kTile - tile_y0_);
  tile_start_.assign(static_cast<size_t>(tiles_x_) * tiles_y_ + 1, 0);
}

void ScreenTiles::Add(int item, const Eigen::Vector3d* corners, int count) {
  if (tiles_x_ == 0 || tiles_y_ == 0 || count == 0) return;
  Eigen::Vector3d lo = corners[0], hi = corners[0];
  double z_min = std::numeric_limits<double>::infinity(), z_max = -z_min;
  for (int k = 0; k < count; ++k) {
    lo = lo.cwiseMin(corners[k]);
    hi = hi.cwiseMax(corners[k]);
    const double z = R_camera_world_.row(2).dot(corners[k] - origin_);
    z_min = std::min(z_min, z);
    z_max = std::max(z_max, z);
  }
  // Pixel rays point forward (camera z > 0): an item wholly behind is never hit.
  if (z_max < -kPad) return;
  Span s{item, 0, tiles_x_ - 1, tile_y0_, tile_y0_ + tiles_y_ - 1, 0};
  if (z_min >= kNearZ) {
    // In front: its projection lies in the hull of its projected corners.
    Eigen::Vector2d p_min = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), p_max = -p_min;
    for (int k = 0; k < count; ++k) {
      const Eigen::Vector2d p = camera_.Project(R_camera_world_ * (corners[k] - origin_));
      p_min = p_min.cwiseMin(p);
      p_max = p_max.cwiseMax(p);
    }
    // Pixel (x, y) has its centre at (x + 0.5, y + 0.5).
    const double x0 = std::ceil(p_min.x() - kMarginPx - 0.5), x1 = std::floor(p_max.x() + kMarginPx - 0.5);
    const double y0 = std::ceil(p_min.y() - kMarginPx - 0.5), y1 = std::floor(p_max.y() + kMarginPx - 0.5);
    if (x1 < 0 || y1 < row_begin_ || x0 > camera_.width - 1 || y0 > row_end_ - 1 || x0 > x1 || y0 > y1) return;
    s.tx0 = static_cast<int>(std::max(0.0, x0)) / kTile;
    s.tx1 = static_cast<int>(std::min<double>(camera_.width - 1, x1)) / kTile;
    s.ty0 = static_cast<int>(std::max<double>(row_begin_, y0)) / kTile;
    s.ty1 = static_cast<int>(std::min<double>(row_end_ - 1, y1)) / kTile;
  }
  // Any hit lies in the padded box: no nearer than the box is to the camera.
  lo.array() -= kPad;
  hi.array() += kPad;
  s.min_distance = (lo - origin_).cwiseMax(origin_ - hi).cwiseMax(0.0).norm() * (1 - 1e-9);
  spans_.push_back(s);
  for (int ty = s.ty0; ty <= s.ty1; ++ty)
    for (int tx = s.tx0; tx <= s.tx1; ++tx) ++tile_start_[static_cast<size_t>(ty - tile_y0_) * tiles_x_ + tx + 1];
}

void ScreenTiles::Finish(bool nearest_first) {
  if (nearest_first)
    std::sort(spans_.begin(), spans_.end(), [](const Span& a, const Span& b) {
      return a.min_distance < b.min_distance || (a.min_distance == b.min_distance && a.item < b.item);
    });
  else
    std::sort(spans_.begin(), spans_.end(), [](const Span& a, const Span& b) { return a.item < b.item; });
  for (size_t i = 1; i < tile_start_.size(); ++i) tile_start_[i] += tile_start_[i - 1];
  entries_.resize(tile_start_.back());
  std::vector<int> fill(tile_start_.begin(), tile_start_.end() - 1);
  for (const Span& s : spans_)
    for (int ty = s.ty0; ty <= s.ty1; ++ty)
      for (int tx = s.tx0; tx <= s.tx1; ++tx)
        entries_[fill[static_cast<size_t>(ty - tile_y0_) * tiles_x_ + tx]++] = {s.min_distance, s.item};
  spans_.clear();
}

}  // namespace locforge::sim

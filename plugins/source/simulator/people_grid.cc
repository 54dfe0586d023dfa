#include "people_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace locforge::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Cells at most: a floor plan kilometres wide gets coarser cells, not gigabytes.
constexpr double kMaxCells = 1 << 16;

// Narrows [t0, t1] to where o + t d has coordinate in [lo, hi]; false when empty.
bool ClipSlab(double o, double d, double lo, double hi, double* t0, double* t1) {
  if (d == 0) return o >= lo && o <= hi;
  double ta = (lo - o) / d, tb = (hi - o) / d;
  if (ta > tb) std::swap(ta, tb);
  *t0 = std::max(*t0, ta);
  *t1 = std::min(*t1, tb);
  return *t0 <= *t1;
}

}  // namespace

PeopleGrid::PeopleGrid(const std::vector<Bound>& bounds, double cell_m) : num_items_(static_cast<int>(bounds.size())) {
  if (bounds.empty()) return;
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(kInf), hi = -lo;
  z0_ = kInf;
  z1_ = -kInf;
  for (const Bound& b : bounds) {
    const double r = b.radius + kMargin;
    lo = lo.cwiseMin(b.center - Eigen::Vector2d(r, r));
    hi = hi.cwiseMax(b.center + Eigen::Vector2d(r, r));
    z0_ = std::min(z0_, b.z0 - kMargin);
    z1_ = std::max(z1_, b.z1 + kMargin);
  }
  const Eigen::Vector2d size = hi - lo;
  cell_ = std::max({cell_m, std::sqrt(size.x() * size.y() / kMaxCells), 1e-3});
  lo_ = lo;
  nx_ = std::max(1, static_cast<int>(std::ceil(size.x() / cell_)));
  ny_ = std::max(1, static_cast<int>(std::ceil(size.y() / cell_)));
  const auto cell_range = [&](double a, double b, int n, double origin, int* first, int* last) {
    *first = std::clamp(static_cast<int>(std::floor((a - origin) / cell_)), 0, n - 1);
    *last = std::clamp(static_cast<int>(std::floor((b - origin) / cell_)), 0, n - 1);
  };
  // Two passes (count, fill) in item order: every cell lists its items ascending.
  cell_start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<int> fill;
    if (pass == 1) {
      for (size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
      items_.resize(cell_start_.back());
      fill.assign(cell_start_.begin(), cell_start_.end() - 1);
    }
    for (int i = 0; i < num_items_; ++i) {
      const Bound& b = bounds[i];
      const double r = b.radius + kMargin;
      int x0, x1, y0, y1;
      cell_range(b.center.x() - r, b.center.x() + r, nx_, lo_.x(), &x0, &x1);
      cell_range(b.center.y() - r, b.center.y() + r, ny_, lo_.y(), &y0, &y1);
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
          const size_t c = static_cast<size_t>(y) * nx_ + x;
          if (pass == 0) ++cell_start_[c + 1];
          else items_[fill[c]++] = i;
        }
    }
  }
}

void PeopleGrid::Candidates(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t0, double t1,
                            std::vector<int>* out) const {
  out->clear();
  if (num_items_ == 0) return;
  // The part of the segment inside the people's height band and the grid.
  if (!ClipSlab(o.z(), d.z(), z0_, z1_, &t0, &t1) ||
      !ClipSlab(o.x(), d.x(), lo_.x(), lo_.x() + nx_ * cell_, &t0, &t1) ||
      !ClipSlab(o.y(), d.y(), lo_.y(), lo_.y() + ny_ * cell_, &t0, &t1))
    return;
  t0 -= kMargin;
  t1 += kMargin;
  // Walk the cells from o + t0 d to o + t1 d (Amanatides & Woo 1987).
  const auto cell_of = [&](double p, double origin, int n) {
    return std::clamp(static_cast<int>(std::floor((p - origin) / cell_)), 0, n - 1);
  };
  int x = cell_of(o.x() + t0 * d.x(), lo_.x(), nx_), y = cell_of(o.y() + t0 * d.y(), lo_.y(), ny_);
  const int step_x = d.x() > 0 ? 1 : -1, step_y = d.y() > 0 ? 1 : -1;
  double next_x = d.x() == 0 ? kInf : (lo_.x() + (x + (step_x > 0)) * cell_ - o.x()) / d.x();
  double next_y = d.y() == 0 ? kInf : (lo_.y() + (y + (step_y > 0)) * cell_ - o.y()) / d.y();
  const double delta_x = d.x() == 0 ? kInf : cell_ / std::abs(d.x());
  const double delta_y = d.y() == 0 ? kInf : cell_ / std::abs(d.y());
  int cells = 0;
  while (true) {
    const size_t c = static_cast<size_t>(y) * nx_ + x;
    if (cell_start_[c] != cell_start_[c + 1]) {
      out->insert(out->end(), items_.begin() + cell_start_[c], items_.begin() + cell_start_[c + 1]);
      ++cells;
    }
    if (next_x <= next_y) {
      if (next_x > t1) break;
      x += step_x;
      next_x += delta_x;
      if (x < 0 || x >= nx_) break;
    } else {
      if (next_y > t1) break;
      y += step_y;
      next_y += delta_y;
      if (y < 0 || y >= ny_) break;
    }
  }
  if (cells > 1) {
    std::sort(out->begin(), out->end());
    out->erase(std::unique(out->begin(), out->end()), out->end());
  }
}

}  // namespace locforge::sim

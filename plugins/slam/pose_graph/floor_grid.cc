#include "floor_grid.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <set>

#include "locforge/error.h"

namespace locforge::lidar {

bool FloorGridOptions::Check(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(cell_m > 0)) return fail("floor grid: cell_m must be > 0");
  if (!(max_height_m > min_height_m)) return fail("floor grid: max_height_m must exceed min_height_m");
  if (!(azimuth_bin_deg > 0 && azimuth_bin_deg <= 90)) return fail("floor grid: azimuth_bin_deg must be in (0, 90]");
  if (!(max_range_m > cell_m)) return fail("floor grid: max_range_m must exceed cell_m");
  if (min_scans_occupied < 1 || min_scans_free < 1) return fail("floor grid: scan counts must be >= 1");
  if (!(tall_max_height_m > tall_min_height_m)) return fail("floor grid: tall_max_height_m must exceed tall_min_height_m");
  if (!(agreement_margin_m >= 0)) return fail("floor grid: agreement_margin_m must be >= 0");
  if (!(min_conflict_extent_m >= 0)) return fail("floor grid: min_conflict_extent_m must be >= 0");
  return true;
}

FloorGrid::FloorGrid(const FloorGridOptions& options, const Eigen::AlignedBox2d& extent) : o_(options) {
  std::string why;
  if (!o_.Check(&why)) throw ParamError(why);
  if (extent.isEmpty()) throw Error("floor grid: empty extent");
  origin_ = extent.min();
  const Eigen::Vector2d size = extent.sizes();
  width_ = static_cast<int>(std::ceil(size.x() / o_.cell_m)) + 1;
  height_ = static_cast<int>(std::ceil(size.y() / o_.cell_m)) + 1;
  // A sanity bound (a floor of 2 km x 2 km at 0.1 m): larger means bad poses.
  if (static_cast<double>(width_) * height_ > 4e8) throw Error("floor grid: extent too large");
  const size_t n = static_cast<size_t>(width_) * height_;
  hit_scans_.assign(n, 0);
  crossed_scans_.assign(n, 0);
  tall_.assign(n, 0);
  last_hit_.assign(n, -1);
  last_crossed_.assign(n, -1);
}

bool FloorGrid::Index(const Eigen::Vector2d& p, int* i) const {
  const double fx = (p.x() - origin_.x()) / o_.cell_m, fy = (p.y() - origin_.y()) / o_.cell_m;
  if (!(fx >= 0 && fy >= 0 && fx < width_ && fy < height_)) return false;
  *i = static_cast<int>(fy) * width_ + static_cast<int>(fx);
  return true;
}

void FloorGrid::AddScan(const Cloud& scan, const Pose& T_world_rig) {
  if (finished_) throw Error("floor grid: AddScan after Finish");
  const int id = scans_++;
  const int bins = static_cast<int>(std::ceil(360.0 / o_.azimuth_bin_deg));
  std::vector<double> nearest(bins, std::numeric_limits<double>::infinity());
  std::vector<Eigen::Vector2d> end(bins);
  const Eigen::Matrix3d R = T_world_rig.q.toRotationMatrix();
  const Eigen::Vector2d o = T_world_rig.t.head<2>();
  auto count = [&](std::vector<uint16_t>& counter, std::vector<int32_t>& last, int i) {
    if (last[i] == id) return;
    last[i] = id;
    if (counter[i] < std::numeric_limits<uint16_t>::max()) ++counter[i];
  };
  for (const Eigen::Vector3f& pf : scan.points) {
    const Eigen::Vector3d p = pf.cast<double>();
    const double range = p.head<2>().norm();
    if (range > o_.max_range_m || range < o_.cell_m) continue;
    const bool tall = p.z() >= o_.tall_min_height_m && p.z() <= o_.tall_max_height_m;
    if (!tall && (p.z() < o_.min_height_m || p.z() > o_.max_height_m)) continue;
    const Eigen::Vector2d w = (R * p + T_world_rig.t).head<2>();
    int i;
    if (tall) {
      if (Index(w, &i)) tall_[i] = 1;
      continue;
    }
    if (Index(w, &i)) count(hit_scans_, last_hit_, i);
    const double azimuth = std::atan2(p.y(), p.x()) + M_PI;
    const int bin = std::min(bins - 1, static_cast<int>(azimuth / (2 * M_PI) * bins));
    if (range < nearest[bin]) nearest[bin] = range, end[bin] = w;
  }
  // Free space: the cells each bin's ray crosses before its nearest return
  // (2-D DDA, Amanatides & Woo 1987), the return's own cell excluded.
  for (int b = 0; b < bins; ++b) {
    if (!std::isfinite(nearest[b])) continue;
    const Eigen::Vector2d d = end[b] - o;
    const double length = d.norm();
    const Eigen::Vector2d dir = d / length;
    double gx = (o.x() - origin_.x()) / o_.cell_m, gy = (o.y() - origin_.y()) / o_.cell_m;
    int cx = static_cast<int>(std::floor(gx)), cy = static_cast<int>(std::floor(gy));
    const int sx = dir.x() > 0 ? 1 : -1, sy = dir.y() > 0 ? 1 : -1;
    const double inf = std::numeric_limits<double>::infinity();
    const double dx = dir.x() != 0 ? o_.cell_m / std::abs(dir.x()) : inf;
    const double dy = dir.y() != 0 ? o_.cell_m / std::abs(dir.y()) : inf;
    double tx = dir.x() != 0 ? ((sx > 0 ? cx + 1 - gx : gx - cx) * o_.cell_m) / std::abs(dir.x()) : inf;
    double ty = dir.y() != 0 ? ((sy > 0 ? cy + 1 - gy : gy - cy) * o_.cell_m) / std::abs(dir.y()) : inf;
    // Stop one cell short of the return: its neighbour may hold the surface.
    const double stop = length - o_.cell_m;
    double t = 0;
    while (t < stop) {
      if (cx >= 0 && cy >= 0 && cx < width_ && cy < height_) count(crossed_scans_, last_crossed_, cy * width_ + cx);
      if (tx < ty) {
        t = tx, tx += dx, cx += sx;
      } else {
        t = ty, ty += dy, cy += sy;
      }
    }
  }
}

void FloorGrid::Finish() {
  if (finished_) return;
  finished_ = true;
  // Distance (in cells, 8-neighbour chessboard) to the nearest cell any scan
  // hit, up to the margin: multi-source breadth-first search.
  const int margin = static_cast<int>(std::ceil(o_.agreement_margin_m / o_.cell_m));
  const size_t n = hit_scans_.size();
  near_occupied_.assign(n, 0);
  std::vector<int16_t> dist(n, -1);
  std::deque<int> queue;
  for (size_t i = 0; i < n; ++i)
    if (hit_scans_[i] > 0) dist[i] = 0, queue.push_back(static_cast<int>(i));
  while (!queue.empty()) {
    const int i = queue.front();
    queue.pop_front();
    near_occupied_[i] = 1;
    if (dist[i] >= margin) continue;
    const int x = i % width_, y = i / width_;
    for (int ddy = -1; ddy <= 1; ++ddy)
      for (int ddx = -1; ddx <= 1; ++ddx) {
        const int nx = x + ddx, ny = y + ddy;
        if (nx < 0 || ny < 0 || nx >= width_ || ny >= height_) continue;
        const int j = ny * width_ + nx;
        if (dist[j] >= 0) continue;
        dist[j] = static_cast<int16_t>(dist[i] + 1);
        queue.push_back(j);
      }
  }
  structure_.clear();
  for (size_t i = 0; i < n; ++i)
    if (hit_scans_[i] >= o_.min_scans_occupied && tall_[i])
      structure_.emplace_back(origin_.x() + (static_cast<double>(i % width_) + 0.5) * o_.cell_m,
                              origin_.y() + (static_cast<double>(i / width_) + 0.5) * o_.cell_m);
  // The per-scan stamps are only needed while scans are added.
  std::vector<int32_t>().swap(last_hit_);
  std::vector<int32_t>().swap(last_crossed_);
}

Eigen::Vector2i FloorGrid::CellOf(const Eigen::Vector2d& p) const {
  return Eigen::Vector2i(static_cast<int>(std::floor((p.x() - origin_.x()) / o_.cell_m)),
                         static_cast<int>(std::floor((p.y() - origin_.y()) / o_.cell_m)));
}

FloorGrid::State FloorGrid::At(const Eigen::Vector2d& p) const {
  int i;
  if (!Index(p, &i)) return State::kUnknown;
  if (hit_scans_[i] > 0) return State::kOccupied;
  if (crossed_scans_[i] >= o_.min_scans_free) return State::kFree;
  return State::kUnknown;
}

bool FloorGrid::NearOccupied(const Eigen::Vector2d& p) const {
  int i;
  return finished_ && Index(p, &i) && near_occupied_[i];
}

double FloorAgreement::ConflictFraction() const {
  const int64_t seen = agreeing + conflicting;
  return seen > 0 ? static_cast<double>(conflicting) / static_cast<double>(seen) : 0.0;
}

FloorAgreement CompareFloors(const FloorGrid& x, const FloorGrid& y, const Pose& T_y_x) {
  FloorAgreement out;
  const Eigen::Matrix3d R = T_y_x.q.toRotationMatrix();
  std::set<std::pair<int, int>> conflicts;  // x's cells
  for (const Eigen::Vector2d& c : x.structure()) {
    const Eigen::Vector2d p = (R * Eigen::Vector3d(c.x(), c.y(), 0) + T_y_x.t).head<2>();
    if (y.NearOccupied(p)) {
      ++out.agreeing;
    } else if (y.At(p) == FloorGrid::State::kFree) {
      const Eigen::Vector2i k = x.CellOf(c);
      conflicts.insert({k.x(), k.y()});
    } else {
      ++out.unseen;
    }
  }
  // Conflicting cells in 8-connected pieces; small pieces are set apart.
  const double cell = x.options().cell_m;
  while (!conflicts.empty()) {
    std::vector<std::pair<int, int>> piece = {*conflicts.begin()};
    conflicts.erase(conflicts.begin());
    Eigen::AlignedBox2i box;
    for (size_t i = 0; i < piece.size(); ++i) {
      const auto [cx, cy] = piece[i];
      box.extend(Eigen::Vector2i(cx, cy));
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const auto it = conflicts.find({cx + dx, cy + dy});
          if (it == conflicts.end()) continue;
          piece.push_back(*it);
          conflicts.erase(it);
        }
    }
    const double extent = ((box.max() - box.min()).cast<double>() + Eigen::Vector2d::Ones()).norm() * cell;
    (extent >= x.options().min_conflict_extent_m ? out.conflicting : out.small_conflicts) +=
        static_cast<int64_t>(piece.size());
  }
  return out;
}

double JoinEvidence::Conflict() const { return std::max(b_in_a.ConflictFraction(), a_in_b.ConflictFraction()); }
int64_t JoinEvidence::Agreeing() const { return std::min(b_in_a.agreeing, a_in_b.agreeing); }

JoinEvidence EvaluateJoin(const FloorGrid& a, const FloorGrid& b, const Pose& T_a_b) {
  JoinEvidence e;
  e.b_in_a = CompareFloors(b, a, T_a_b);
  e.a_in_b = CompareFloors(a, b, T_a_b.Inverse());
  return e;
}

}  // namespace locforge::lidar

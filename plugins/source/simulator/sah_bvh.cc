#include "sah_bvh.h"

#include <algorithm>
#include <cmath>

#include "raycast.h"

namespace locforge::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Boxes are padded by far more than any rounding of the slab test, so a box
// whose quad the ray hits at t is always entered before t.
constexpr double kPad = 1e-6;
constexpr int kBins = 16;
constexpr int kLeafSize = 2;     // a leaf of at most this many quads is never split
constexpr int kMaxLeafSize = 8;  // split larger ones even when the heuristic says not to
constexpr double kTraversalCost = 1.0;  // relative to one ray-quad test

}  // namespace

double SahBvh::Box::Area() const {
  const Eigen::Vector3d e = (hi - lo).cwiseMax(0.0);
  return 2 * (e.x() * e.y() + e.y() * e.z() + e.z() * e.x());
}

SahBvh::SahBvh(const std::vector<Quad>& quads) : quads_(quads) {
  std::vector<Box> boxes(quads.size());
  std::vector<Eigen::Vector3d> centroids(quads.size());
  for (size_t i = 0; i < quads.size(); ++i) {
    const Quad& q = quads[i];
    for (const Eigen::Vector3d& p : {q.origin, Eigen::Vector3d(q.origin + q.u_edge),
                                     Eigen::Vector3d(q.origin + q.v_edge),
                                     Eigen::Vector3d(q.origin + q.u_edge + q.v_edge)}) {
      boxes[i].lo = boxes[i].lo.cwiseMin(p);
      boxes[i].hi = boxes[i].hi.cwiseMax(p);
    }
    boxes[i].lo.array() -= kPad;
    boxes[i].hi.array() += kPad;
    centroids[i] = 0.5 * (boxes[i].lo + boxes[i].hi);
  }
  order_.resize(quads.size());
  for (size_t i = 0; i < order_.size(); ++i) order_[i] = static_cast<int>(i);
  if (!quads.empty()) root_ = Build(0, static_cast<int>(quads.size()), 0, boxes, centroids, &root_box_);
}

// The centroids in kBins slabs along each axis; for each boundary, the
// boxes' areas times their counts on both sides.
void SahBvh::CheapestSplit(int first, int count, const Box& centres, const std::vector<Box>& boxes,
                           const std::vector<Eigen::Vector3d>& centroids, double* best_cost, int* best_axis,
                           int* best_bin) const {
  for (int axis = 0; axis < 3; ++axis) {
    const double lo = centres.lo[axis], extent = centres.hi[axis] - lo;
    if (!(extent > 0)) continue;
    Box bin_box[kBins];
    int bin_count[kBins] = {};
    for (int i = first; i < first + count; ++i) {
      const int b = std::min(kBins - 1, static_cast<int>(kBins * (centroids[order_[i]][axis] - lo) / extent));
      bin_box[b].Grow(boxes[order_[i]]);
      ++bin_count[b];
    }
    double right_area[kBins];
    int right_count[kBins];
    Box acc;
    int n = 0;
    for (int b = kBins - 1; b > 0; --b) {
      acc.Grow(bin_box[b]);
      n += bin_count[b];
      right_area[b] = acc.Area();
      right_count[b] = n;
    }
    acc = Box();
    n = 0;
    for (int b = 0; b < kBins - 1; ++b) {  // left: bins [0, b], right: [b + 1, kBins)
      acc.Grow(bin_box[b]);
      n += bin_count[b];
      if (n == 0 || right_count[b + 1] == 0) continue;
      const double cost = acc.Area() * n + right_area[b + 1] * right_count[b + 1];
      if (cost < *best_cost) {
        *best_cost = cost;
        *best_axis = axis;
        *best_bin = b;
      }
    }
  }
}

int SahBvh::Build(int first, int count, int depth, const std::vector<Box>& boxes,
                  const std::vector<Eigen::Vector3d>& centroids, Box* bounds) {
  depth_ = std::max(depth_, depth);
  Box all, centres;
  for (int i = first; i < first + count; ++i) {
    all.Grow(boxes[order_[i]]);
    centres.Grow({centroids[order_[i]], centroids[order_[i]]});
  }
  *bounds = all;
  const auto make_leaf = [&] {
    leaves_.push_back({first, count});
    return -static_cast<int>(leaves_.size());
  };
  if (count <= kLeafSize || depth >= kMaxDepth - 1) return make_leaf();

  double best_cost = kInf;
  int best_axis = -1, best_bin = 0;
  CheapestSplit(first, count, centres, boxes, centroids, &best_cost, &best_axis, &best_bin);
  const double area = all.Area();
  const bool worth_it = area > 0 && kTraversalCost + best_cost / area < count;
  int mid;
  if (best_axis >= 0 && (worth_it || count > kMaxLeafSize)) {
    const double lo = centres.lo[best_axis], extent = centres.hi[best_axis] - lo;
    mid = static_cast<int>(std::partition(order_.begin() + first, order_.begin() + first + count,
                                          [&](int q) {
                                            return std::min(kBins - 1, static_cast<int>(kBins * (centroids[q][best_axis] - lo) / extent)) <= best_bin;
                                          }) - order_.begin());
  } else if (count > kMaxLeafSize) {
    mid = first + count / 2;  // all centroids coincide: split by count
  } else {
    return make_leaf();
  }
  const int index = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  Box left_box, right_box;
  const int left = Build(first, mid - first, depth + 1, boxes, centroids, &left_box);
  const int right = Build(mid, first + count - mid, depth + 1, boxes, centroids, &right_box);
  for (int axis = 0; axis < 3; ++axis) {
    nodes_[index].bounds[axis][0][0] = left_box.lo[axis];
    nodes_[index].bounds[axis][1][0] = left_box.hi[axis];
    nodes_[index].bounds[axis][0][1] = right_box.lo[axis];
    nodes_[index].bounds[axis][1][1] = right_box.hi[axis];
  }
  nodes_[index].child[0] = left;
  nodes_[index].child[1] = right;
  return index;
}

NearestQuadSearch SahBvh::Intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                                    double t_max) const {
  NearestQuadSearch best;
  best.t = t_max;
  if (quads_.empty()) return best;
  const Eigen::Vector3d inv_d = d.cwiseInverse();
  // Per axis, the bound the ray leaves a box through: hi (1) when d >= 0.
  const int far[3] = {d.x() >= 0, d.y() >= 0, d.z() >= 0};
  struct Pending {
    int code;      // node, or -1 - leaf
    double entry;  // where the ray enters its box
  };
  Pending stack[kMaxDepth + 4];
  int top = 0;
  const double root_entry = BoxEntry(root_box_.lo, root_box_.hi, o, inv_d, best.t);
  if (root_entry < best.t) stack[top++] = {root_, root_entry};
  while (top > 0) {
    const Pending p = stack[--top];
    // A quad hit at exactly best.t lies inside its padded boxes, which the ray
    // enters strictly before best.t: ties are never pruned away.
    if (!(p.entry < best.t)) continue;
    if (p.code < 0) {
      const Leaf& leaf = leaves_[-1 - p.code];
      for (int i = leaf.first; i < leaf.first + leaf.count; ++i)
        best.Test(quads_[order_[i]], order_[i], o, d, t_min);
      continue;
    }
    const Node& n = nodes_[p.code];
    double entry[2], exit[2];
    for (int c = 0; c < 2; ++c) {
      entry[c] = 0;
      exit[c] = best.t;
    }
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 2; ++c) {
        entry[c] = std::max(entry[c], (n.bounds[a][far[a] ^ 1][c] - o[a]) * inv_d[a]);
        exit[c] = std::min(exit[c], (n.bounds[a][far[a]][c] - o[a]) * inv_d[a]);
      }
    const double t0 = entry[0] <= exit[0] ? entry[0] : kInf;
    const double t1 = entry[1] <= exit[1] ? entry[1] : kInf;
    // Nearer child on top of the stack.
    if (t0 < t1) {
      if (t1 < best.t) stack[top++] = {n.child[1], t1};
      if (t0 < best.t) stack[top++] = {n.child[0], t0};
    } else {
      if (t0 < best.t) stack[top++] = {n.child[0], t0};
      if (t1 < best.t) stack[top++] = {n.child[1], t1};
    }
  }
  return best;
}

}  // namespace locforge::sim

#include "kdtree.h"

#include <algorithm>
#include <limits>
#include <numeric>

namespace locforge::gicp {

namespace {
constexpr int kLeafSize = 12;
}

KdTree::KdTree(const Points& points) : order_(points.size()) {
  std::iota(order_.begin(), order_.end(), 0);
  nodes_.reserve(2 * points.size() / kLeafSize + 2);
  if (points.empty()) return;
  Build(points, 0, static_cast<int>(points.size()));
  position_.resize(points.size());
  for (size_t i = 0; i < order_.size(); ++i) position_[order_[i]] = static_cast<int>(i);
  x_.resize(points.size());
  y_.resize(points.size());
  z_.resize(points.size());
  lo_ = hi_ = points[0];
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d& p = points[order_[i]];
    x_[i] = p.x();
    y_[i] = p.y();
    z_[i] = p.z();
    lo_ = lo_.cwiseMin(p);
    hi_ = hi_.cwiseMax(p);
  }
}

// Built on order_ (indices into `points`), so nth_element moves 4-byte
// indices; the constructor gathers the points afterwards.
int KdTree::Build(const Points& points, int begin, int end) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.push_back(Node{-1, begin, end});
  if (end - begin <= kLeafSize) return id;
  Eigen::Vector3d lo = points[order_[begin]], hi = lo;
  for (int i = begin + 1; i < end; ++i) {
    lo = lo.cwiseMin(points[order_[i]]);
    hi = hi.cwiseMax(points[order_[i]]);
  }
  int axis;
  (hi - lo).maxCoeff(&axis);
  const int mid = begin + (end - begin) / 2;
  const auto less = [&](int a, int b) { return points[a][axis] < points[b][axis]; };
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end, less);
  const double high = points[order_[mid]][axis];  // the right half's smallest
  const double low = points[*std::max_element(order_.begin() + begin, order_.begin() + mid, less)][axis];
  Build(points, begin, mid);  // the left child is node id + 1
  const int right = Build(points, mid, end);
  Node& n = nodes_[id];
  n.axis = axis;
  n.low = low;
  n.high = high;
  n.right = right;
  return id;
}

// Depth-first, nearer child first, pruned with an incremental lower bound of
// the squared distance to a node's cell (nanoflann's trick): `axis_sq_dist`
// holds, per axis, the squared distance from q to the cell's slab, and
// `min_sq_dist` their sum. Iterative: each descent to a leaf stacks the
// farther children, popped (deepest first) when still within `v.bound()`,
// the current squared search radius; `v.Add(i, d2)` offers the point at tree
// position i.
template <typename Visitor>
void KdTree::SearchFromRoot(const Eigen::Vector3d& q, Visitor& v) const {
  struct Cell {
    int node;
    double min_sq_dist;
    Eigen::Vector3d axis_sq_dist;
  };
  Cell stack[64];  // deeper than any tree of < 2^31 points
  int top = 0;
  const Eigen::Vector3d to_box = (q.cwiseMax(lo_).cwiseMin(hi_) - q).cwiseAbs2();
  stack[top++] = Cell{0, to_box.sum(), to_box};
  while (top > 0) {
    const Cell cell = stack[--top];
    if (cell.min_sq_dist >= v.bound()) continue;
    int node = cell.node;
    for (const Node* n = &nodes_[node]; n->axis >= 0; n = &nodes_[node]) {
      const double to_low = q[n->axis] - n->low, to_high = q[n->axis] - n->high;
      const bool left_first = to_low + to_high < 0;  // q nearer the left child's side of the gap
      const double cut = left_first ? to_high * to_high : to_low * to_low;
      Cell far{left_first ? n->right : node + 1, cell.min_sq_dist + cut - cell.axis_sq_dist[n->axis],
               cell.axis_sq_dist};
      far.axis_sq_dist[n->axis] = cut;
      if (far.min_sq_dist < v.bound()) stack[top++] = far;
      node = left_first ? node + 1 : n->right;
    }
    // A leaf: all its distances first (a loop the compiler vectorises), then the offers.
    const Node& leaf = nodes_[node];
    double d2[kLeafSize];
    const int m = leaf.end - leaf.begin;
    const double *x = &x_[leaf.begin], *y = &y_[leaf.begin], *z = &z_[leaf.begin];
    for (int i = 0; i < m; ++i) {
      const double dx = x[i] - q.x(), dy = y[i] - q.y(), dz = z[i] - q.z();
      d2[i] = dx * dx + dy * dy + dz * dz;
    }
    for (int i = 0; i < m; ++i)
      if (d2[i] < v.bound()) v.Add(leaf.begin + i, d2[i]);
  }
}

namespace {
struct Best {
  double d2;
  int pos = -1;
  double bound() const { return d2; }
  void Add(int i, double d) {
    if (d < d2) {
      d2 = d;
      pos = i;
    }
  }
};
}  // namespace

bool KdTree::NearestFrom(const Eigen::Vector3d& q, double max_sq_dist, int* index, double* sq_dist) const {
  if (nodes_.empty()) return false;
  Best best{max_sq_dist};
  if (*index >= 0 && *index < static_cast<int>(position_.size())) {
    const int pos = position_[*index];
    // Computed as a leaf computes it, so the hint compares exactly.
    const double dx = x_[pos] - q.x(), dy = y_[pos] - q.y(), dz = z_[pos] - q.z();
    const double d2 = dx * dx + dy * dy + dz * dz;
    if (d2 < max_sq_dist) best = Best{d2, pos};
  }
  SearchFromRoot(q, best);
  if (best.pos < 0) return false;
  *index = order_[best.pos];
  *sq_dist = best.d2;
  return true;
}

bool KdTree::Nearest(const Eigen::Vector3d& q, double max_sq_dist, int* index,
                     double* sq_dist) const {
  int from = -1;  // no hint: a cold search
  if (!NearestFrom(q, max_sq_dist, &from, sq_dist)) return false;
  *index = from;
  return true;
}

void KdTree::KNearest(const Eigen::Vector3d& q, int k, std::vector<int>* indices,
                      std::vector<double>* sq_dists, double max_sq_dist) const {
  // The k best so far, sorted, in caller-provided arrays (k is small:
  // insertion from the back is cheapest).
  struct KBest {
    int k, n = 0;
    int* pos;
    double* d2;
    double worst;  // d2[k - 1] once full; before, the caller's bound
    double bound() const { return worst; }
    void Add(int i, double d) {
      if (d >= worst) return;
      int j = n < k ? n++ : k - 1;
      for (; j > 0 && d2[j - 1] > d; --j) {
        d2[j] = d2[j - 1];
        pos[j] = pos[j - 1];
      }
      d2[j] = d;
      pos[j] = i;
      if (n == k) worst = d2[k - 1];
    }
  };
  k = std::max(0, std::min(k, static_cast<int>(size())));
  indices->resize(k);
  sq_dists->resize(k);
  if (k == 0) return;
  KBest best{k, 0, indices->data(), sq_dists->data(), max_sq_dist};
  SearchFromRoot(q, best);
  indices->resize(best.n);
  sq_dists->resize(best.n);
  for (int& i : *indices) i = order_[i];
}

}  // namespace locforge::gicp

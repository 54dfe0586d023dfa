#include "kdtree.h"

#include <algorithm>
#include <limits>
#include <numeric>

namespace locforge::gicp {

namespace {
constexpr int kLeafSize = 12;
}

KdTree::KdTree(const Points& points) : points_(points), order_(points.size()) {
  std::iota(order_.begin(), order_.end(), 0);
  nodes_.reserve(2 * points.size() / kLeafSize + 2);
  if (!points.empty()) Build(0, static_cast<int>(points.size()));
}

int KdTree::Build(int begin, int end) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.push_back(Node{begin, end});
  if (end - begin <= kLeafSize) return id;
  Eigen::Vector3d lo = points_[order_[begin]], hi = lo;
  for (int i = begin + 1; i < end; ++i) {
    lo = lo.cwiseMin(points_[order_[i]]);
    hi = hi.cwiseMax(points_[order_[i]]);
  }
  int axis;
  (hi - lo).maxCoeff(&axis);
  const int mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](int a, int b) { return points_[a][axis] < points_[b][axis]; });
  const double split = points_[order_[mid]][axis];
  const int left = Build(begin, mid);
  const int right = Build(mid, end);
  Node& n = nodes_[id];
  n.axis = axis;
  n.split = split;
  n.left = left;
  n.right = right;
  return id;
}

// Depth-first descent, nearer child first; `v.bound()` is the current
// squared search radius and `v.Add(i, d2)` offers a candidate.
template <typename Visitor>
void KdTree::Search(int node, const Eigen::Vector3d& q, Visitor& v) const {
  const Node& n = nodes_[node];
  if (n.axis < 0) {
    for (int i = n.begin; i < n.end; ++i) {
      const int idx = order_[i];
      v.Add(idx, (points_[idx] - q).squaredNorm());
    }
    return;
  }
  const double diff = q[n.axis] - n.split;
  const int near = diff < 0 ? n.left : n.right;
  const int far = diff < 0 ? n.right : n.left;
  Search(near, q, v);
  if (diff * diff < v.bound()) Search(far, q, v);
}

bool KdTree::Nearest(const Eigen::Vector3d& q, double max_sq_dist, int* index,
                     double* sq_dist) const {
  struct Best {
    double d2;
    int idx = -1;
    double bound() const { return d2; }
    void Add(int i, double d) {
      if (d < d2) {
        d2 = d;
        idx = i;
      }
    }
  } best{max_sq_dist};
  if (nodes_.empty()) return false;
  Search(0, q, best);
  if (best.idx < 0) return false;
  *index = best.idx;
  *sq_dist = best.d2;
  return true;
}

void KdTree::KNearest(const Eigen::Vector3d& q, int k, std::vector<int>* indices,
                      std::vector<double>* sq_dists) const {
  // A sorted array of the k best so far (k is small: insertion is cheapest).
  struct KBest {
    int k;
    std::vector<int>* idx;
    std::vector<double>* d2;
    double bound() const {
      return static_cast<int>(d2->size()) < k ? std::numeric_limits<double>::infinity()
                                              : d2->back();
    }
    void Add(int i, double d) {
      if (d >= bound()) return;
      if (static_cast<int>(d2->size()) == k) {
        d2->pop_back();
        idx->pop_back();
      }
      const auto at = std::upper_bound(d2->begin(), d2->end(), d);
      idx->insert(idx->begin() + (at - d2->begin()), i);
      d2->insert(at, d);
    }
  } best{k, indices, sq_dists};
  indices->clear();
  sq_dists->clear();
  if (nodes_.empty() || k <= 0) return;
  Search(0, q, best);
}

}  // namespace locforge::gicp

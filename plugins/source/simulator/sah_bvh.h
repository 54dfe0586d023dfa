// A second BVH over the scene's quads, built for speed: binned surface-area
// heuristic (the floor, ceiling and long walls end up near the root and give
// rays a close bound early), both children's boxes stored in their parent.
// It finds the nearest quad and tells whether another quad is hit at exactly
// the same distance. Only then does the order in which quads are tested
// decide the hit (the first one tested wins): World::CastNear hands such rays
// to QuadBvh, whose order defines the simulator's output, so every hit equals
// QuadBvh's bit for bit.
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_SAH_BVH_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_SAH_BVH_H_

#include <Eigen/Core>
#include <algorithm>
#include <limits>
#include <vector>

#include "scene.h"

namespace locforge::sim {

// Slab test of the ray o + t d (inv_d = 1 / d per axis) against the box
// [lo, hi]: the entry distance when the box is entered before t_max, else +inf.
// The BVHs of raycast.h and of this file both traverse with it.
inline double BoxEntry(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const Eigen::Vector3d& o,
                       const Eigen::Vector3d& inv_d, double t_max) {
  double t0 = 0, t1 = t_max;
  for (int a = 0; a < 3; ++a) {
    double ta = (lo[a] - o[a]) * inv_d[a], tb = (hi[a] - o[a]) * inv_d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return std::numeric_limits<double>::infinity();
  }
  return t0;
}

struct NearestQuadSearch;  // raycast.h

class SahBvh {
 public:
  // Keeps a reference to `quads`, which must outlive the BVH.
  explicit SahBvh(const std::vector<Quad>& quads);

  // The nearest quad along o + t d with t in (t_min, t_max), and its ties.
  NearestQuadSearch Intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                              double t_max) const;

  size_t num_nodes() const { return nodes_.size(); }
  int depth() const { return depth_; }

 private:
  struct Box {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector3d hi = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());
    void Grow(const Box& b) {
      lo = lo.cwiseMin(b.lo);
      hi = hi.cwiseMax(b.hi);
    }
    double Area() const;
  };
  // Both children's boxes, bounds[axis][0 = lo, 1 = hi][child]; children:
  // >= 0 an inner node, < 0 the leaf -1 - child.
  struct Node {
    double bounds[3][2][2];
    int child[2] = {-1, -1};
  };
  struct Leaf {
    int first = 0, count = 0;  // range in order_
  };
  static constexpr int kMaxDepth = 60;

  int Build(int first, int count, int depth, const std::vector<Box>& boxes,
            const std::vector<Eigen::Vector3d>& centroids, Box* bounds);
  // The cheapest split of order_[first, first + count) (surface area
  // heuristic over binned centroids): its cost, axis (-1: none) and last left bin.
  void CheapestSplit(int first, int count, const Box& centres, const std::vector<Box>& boxes,
                     const std::vector<Eigen::Vector3d>& centroids, double* best_cost, int* best_axis,
                     int* best_bin) const;

  const std::vector<Quad>& quads_;
  std::vector<int> order_;
  std::vector<Node> nodes_;
  std::vector<Leaf> leaves_;
  int root_ = -1;
  Box root_box_;
  int depth_ = 0;
};

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_SAH_BVH_H_

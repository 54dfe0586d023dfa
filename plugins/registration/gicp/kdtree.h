// A static 3-D KD-tree over a point array (median split on the widest axis,
// small leaves): nearest neighbour for correspondences, k nearest for
// covariances. Eigen only; read-only after construction, so searches may run
// from many threads.
#ifndef LOCFORGE_PLUGINS_REGISTRATION_GICP_KDTREE_H_
#define LOCFORGE_PLUGINS_REGISTRATION_GICP_KDTREE_H_

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <vector>

namespace locforge::gicp {

using Points = std::vector<Eigen::Vector3d>;

class KdTree {
 public:
  // Keeps its own copy of `points` in tree order (each leaf contiguous, one
  // array per axis so a leaf's distances vectorise); searches return indices
  // into `points`.
  explicit KdTree(const Points& points);

  // Index of the nearest point and its squared distance; false when no point
  // lies within sqrt(max_sq_dist).
  bool Nearest(const Eigen::Vector3d& q, double max_sq_dist, int* index, double* sq_dist) const;
  // The same answer, warm-started from `*index` when it is a point's index
  // (>= 0): that point's distance bounds the search from its first step (an
  // optimizer's previous correspondence, a few millimetres off). Ties may
  // keep the hint where a cold search picks another point at equal distance.
  bool NearestFrom(const Eigen::Vector3d& q, double max_sq_dist, int* index, double* sq_dist) const;
  // Up to k nearest points, closest first (fewer when the cloud is smaller).
  // Reuses the vectors' storage: no allocation once they have held k items.
  // `max_sq_dist`: a bound known to hold at least k points (the caller's
  // warm start: EstimateCovariances); the answer is the same, found sooner.
  void KNearest(const Eigen::Vector3d& q, int k, std::vector<int>* indices,
                std::vector<double>* sq_dists,
                double max_sq_dist = std::numeric_limits<double>::infinity()) const;

  size_t size() const { return order_.size(); }
  // Input indices in tree order: visiting points in this order keeps
  // successive queries close to each other.
  const std::vector<int>& order() const { return order_; }

 private:
  // Inner nodes split on `axis`; the left child (the next node) holds the
  // points with coordinate <= low, the right child those >= high.
  struct Node {
    int axis = -1;  // -1 for a leaf
    int begin = 0, end = 0;  // leaf: range in tree order
    int right = -1;
    double low = 0, high = 0;
  };
  int Build(const Points& points, int begin, int end);
  template <typename Visitor>
  void SearchFromRoot(const Eigen::Vector3d& q, Visitor& v) const;

  std::vector<double> x_, y_, z_;  // the points in tree order
  std::vector<int> order_;         // input index of each
  std::vector<int> position_;      // tree position of each input index
  std::vector<Node> nodes_;
  Eigen::Vector3d lo_, hi_;  // bounding box of all points
};

}  // namespace locforge::gicp

#endif  // LOCFORGE_PLUGINS_REGISTRATION_GICP_KDTREE_H_

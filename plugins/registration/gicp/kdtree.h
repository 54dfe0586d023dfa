// A static 3-D KD-tree over a point array (median split on the widest axis,
// small leaves): nearest neighbour for correspondences, k nearest for
// covariances. Eigen only; read-only after construction, so searches may run
// from many threads.
#ifndef LOCFORGE_PLUGINS_REGISTRATION_GICP_KDTREE_H_
#define LOCFORGE_PLUGINS_REGISTRATION_GICP_KDTREE_H_

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace locforge::gicp {

using Points = std::vector<Eigen::Vector3d>;

class KdTree {
 public:
  explicit KdTree(const Points& points);  // keeps a reference: `points` must outlive the tree

  // Index of the nearest point and its squared distance; false when no point
  // lies within sqrt(max_sq_dist).
  bool Nearest(const Eigen::Vector3d& q, double max_sq_dist, int* index, double* sq_dist) const;
  // Up to k nearest points, closest first (fewer when the cloud is smaller).
  void KNearest(const Eigen::Vector3d& q, int k, std::vector<int>* indices,
                std::vector<double>* sq_dists) const;

 private:
  struct Node {
    int begin = 0, end = 0;  // range in order_ (leaves)
    int left = -1, right = -1;
    int axis = -1;           // -1 for a leaf
    double split = 0;
  };
  int Build(int begin, int end);
  template <typename Visitor>
  void Search(int node, const Eigen::Vector3d& q, Visitor& v) const;

  const Points& points_;
  std::vector<int> order_;
  std::vector<Node> nodes_;
};

}  // namespace locforge::gicp

#endif  // LOCFORGE_PLUGINS_REGISTRATION_GICP_KDTREE_H_

#include "gicp/point_to_plane.h"

namespace locforge::gicp {

LinearSystem PointToPlaneSystem(const Points& source, const Points& target,
                                const Points& target_normals, const KdTree& target_tree,
                                const Eigen::Isometry3d& T, double max_correspondence_distance,
                                int threads) {
  constexpr int kBlocks = 64;
  const int64_t n = static_cast<int64_t>(source.size());
  const double max_sq = max_correspondence_distance * max_correspondence_distance;
  std::vector<LinearSystem> blocks(kBlocks);
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1)
  for (int blk = 0; blk < kBlocks; ++blk) {
    LinearSystem& s = blocks[blk];
    for (int64_t i = n * blk / kBlocks; i < n * (blk + 1) / kBlocks; ++i) {
      const Eigen::Vector3d p = T * source[i];
      int j;
      double d2;
      if (!target_tree.Nearest(p, max_sq, &j, &d2)) continue;
      const Eigen::Vector3d& nrm = target_normals[j];
      if (!nrm.allFinite()) continue;
      const double r = nrm.dot(target[j] - p);
      Vector6d J;
      J << nrm.cross(p), -nrm;  // n^T [p]x w = (n x p) . w
      s.H.noalias() += J * J.transpose();
      s.b += J * r;
      s.cost += r * r;
      ++s.inliers;
    }
  }
  LinearSystem total;
  for (const LinearSystem& s : blocks) total += s;
  return total;
}

}  // namespace locforge::gicp

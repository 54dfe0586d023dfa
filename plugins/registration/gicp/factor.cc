#include "factor.h"

#include <algorithm>
#include <cmath>

namespace locforge::gicp {

namespace {
constexpr int kBlocks = 64;  // fixed summation blocks: same sums for any thread count

// Nearest target point to q, starting from `*j` (a correspondence of the
// previous iteration): moves to the closest point of the current one's
// neighbour list while that is closer to q. The result b is certified exact
// when 2 |q - b| < radius[b]: a point p closer to q than b lies within
// |p - b| <= |p - q| + |q - b| < 2 |q - b| of b (triangle inequality), so in
// b's list, which was scanned. Returns false when not certified (then the
// caller searches the tree, from *j, now b).
bool NearestByWalk(const Eigen::Vector3d& q, const Points& target, const NeighborGraph& g, int* j,
                   double* d2) {
  constexpr int kMaxSteps = 8;
  auto dist2 = [&](int i) {  // as KdTree's leaves compute it, so answers compare exactly
    const double dx = target[i].x() - q.x(), dy = target[i].y() - q.y(), dz = target[i].z() - q.z();
    return dx * dx + dy * dy + dz * dz;
  };
  int best = *j;
  double best_d2 = dist2(best);
  for (int step = 0; step < kMaxSteps; ++step) {
    const int* list = &g.ids[static_cast<size_t>(best) * g.k];
    int next = best;
    double next_d2 = best_d2;
    for (int n = 0; n < g.k; ++n) {
      if (list[n] < 0) continue;  // never filled (cannot happen; EstimateCovariances)
      const double d = dist2(list[n]);
      if (d < next_d2) {
        next_d2 = d;
        next = list[n];
      }
    }
    if (next == best) {
      *j = best;
      *d2 = best_d2;
      return 4 * best_d2 < g.radius[best] * g.radius[best];
    }
    best = next;
    best_d2 = next_d2;
  }
  *j = best;
  return false;
}

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}
}  // namespace

double RobustWeight(RobustKernel kernel, double width, double e) {
  switch (kernel) {
    case RobustKernel::kHuber: {
      const double s = std::sqrt(e);
      return s <= width ? 1.0 : width / s;
    }
    case RobustKernel::kCauchy:
      return 1.0 / (1.0 + e / (width * width));
    default:
      return 1.0;
  }
}

double RobustCost(RobustKernel kernel, double width, double e) {
  switch (kernel) {
    case RobustKernel::kHuber: {
      const double s = std::sqrt(e);
      return s <= width ? e : 2 * width * s - width * width;
    }
    case RobustKernel::kCauchy:
      return width * width * std::log1p(e / (width * width));
    default:
      return e;
  }
}

LinearSystem Linearize(const GicpInputs& in, const Eigen::Isometry3d& T, const FactorOptions& o,
                       int threads, std::vector<int>* correspondences) {
  const Points& source = *in.source;
  const Points& target = *in.target;
  const int64_t n = static_cast<int64_t>(source.size());
  const double max_sq = o.max_correspondence_distance * o.max_correspondence_distance;
  const Eigen::Matrix3d R = T.linear();
  std::vector<LinearSystem> blocks(kBlocks);
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1)
  for (int blk = 0; blk < kBlocks; ++blk) {
    LinearSystem& sys = blocks[blk];
    const int64_t begin = n * blk / kBlocks, end = n * (blk + 1) / kBlocks;
    for (int64_t i = begin; i < end; ++i) {
      const Eigen::Vector3d p = T * source[i];
      int j = correspondences ? (*correspondences)[i] : -1;
      double d2;
      bool paired;
      if (j >= 0 && in.target_neighbors && in.target_neighbors->k > 0 &&
          NearestByWalk(p, target, *in.target_neighbors, &j, &d2)) {
        paired = d2 < max_sq;  // the certified nearest; beyond the gate: none, as the tree would say
        ++sys.walked;
      } else {
        paired = in.target_tree->NearestFrom(p, max_sq, &j, &d2);
      }
      if (correspondences) (*correspondences)[i] = paired ? j : -1;
      if (!paired) continue;  // rejector
      // Segal et al. eq. 2: combined covariance of the pair in the target frame.
      const Eigen::Matrix3d C = (*in.target_cov)[j] + R * (*in.source_cov)[i] * R.transpose();
      const Eigen::Matrix3d M = C.inverse();
      const Eigen::Vector3d r = target[j] - p;
      const Eigen::Vector3d Mr = M * r;
      const double e = r.dot(Mr);
      const double w = RobustWeight(o.kernel, o.kernel_width, e);
      // J = [ [p]x, -I ] in blocks, with [p]x^T = -[p]x and PM = [p]x M:
      // J^T M J = [ PM [p]x^T, PM ; PM^T, M ],  J^T M r = [ -p x Mr ; -Mr ].
      // The lower-left block is filled from the upper-right one at the end.
      const Eigen::Matrix3d P = Skew(p);
      const Eigen::Matrix3d PM = P * M;
      sys.H.topLeftCorner<3, 3>().noalias() -= w * PM * P;
      sys.H.topRightCorner<3, 3>().noalias() += w * PM;
      sys.H.bottomRightCorner<3, 3>().noalias() += w * M;
      sys.b.head<3>() -= w * p.cross(Mr);
      sys.b.tail<3>() -= w * Mr;
      sys.cost += RobustCost(o.kernel, o.kernel_width, e);
      ++sys.inliers;
    }
  }
  LinearSystem total;
  for (const LinearSystem& s : blocks) total += s;
  total.H.bottomLeftCorner<3, 3>() = total.H.topRightCorner<3, 3>().transpose();
  return total;
}

}  // namespace locforge::gicp

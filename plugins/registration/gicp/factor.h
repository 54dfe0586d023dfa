// The GICP factor (Segal et al. 2009, eq. 2): for a source point s with
// covariance C_s and its nearest target point t with covariance C_t, under
// the transform T = (R, p):
//   r = t - (R s + p),   e = r^T (C_t + R C_s R^T)^-1 r.
// Linearize() sums, over correspondences within the rejection distance, the
// robust-weighted Gauss-Newton system H = sum w J^T M J, b = sum w J^T M r
// for a left perturbation T <- (Exp(w), v) T, with J = [ [Rs+p]x, -I ].
#ifndef LOCFORGE_PLUGINS_REGISTRATION_GICP_FACTOR_H_
#define LOCFORGE_PLUGINS_REGISTRATION_GICP_FACTOR_H_

#include <Eigen/Geometry>

#include "kdtree.h"
#include "locforge/pose.h"
#include "preprocess.h"

namespace locforge::gicp {

enum class RobustKernel { kNone, kHuber, kCauchy };

// IRLS weight of a squared Mahalanobis residual e for the kernel of width k
// (in units of sqrt(e)): Huber w = min(1, k / sqrt(e)); Cauchy w = 1 / (1 + e / k^2).
double RobustWeight(RobustKernel kernel, double width, double e);
// The robust cost rho(e) whose IRLS weight that is (rho(e) = e for kNone).
double RobustCost(RobustKernel kernel, double width, double e);

struct GicpInputs {
  const Points* source;
  const Covariances* source_cov;
  const Points* target;
  const Covariances* target_cov;
  const KdTree* target_tree;
  // Optional: the target's neighbour lists. With them, a search warm-started
  // from a previous correspondence walks the lists first and keeps the
  // answer when a certificate proves it the nearest (factor.cc), else asks
  // the tree: the same pairs, at a fraction of the cost in later iterations.
  const NeighborGraph* target_neighbors = nullptr;
};

struct FactorOptions {
  double max_correspondence_distance = 1.0;  // rejector: farther pairs are ignored
  RobustKernel kernel = RobustKernel::kNone;
  double kernel_width = 1.0;
};

struct LinearSystem {
  Matrix6d H = Matrix6d::Zero();
  Vector6d b = Vector6d::Zero();
  double cost = 0;       // sum of rho(e) over inliers
  uint64_t inliers = 0;
  uint64_t walked = 0;   // correspondence searches answered by the neighbour walk
  LinearSystem& operator+=(const LinearSystem& o) {
    H += o.H;
    b += o.b;
    cost += o.cost;
    inliers += o.inliers;
    walked += o.walked;
    return *this;
  }
};

// Deterministic for any thread count: points are summed in fixed blocks.
// `correspondences` (optional, one per source point, -1: none yet): each
// search starts from the point's previous correspondence and stores the new
// one, so an optimizer's later iterations, moving points by millimetres,
// search little (the same pairs as cold searches).
LinearSystem Linearize(const GicpInputs& in, const Eigen::Isometry3d& T, const FactorOptions& o,
                       int threads, std::vector<int>* correspondences = nullptr);

}  // namespace locforge::gicp

#endif  // LOCFORGE_PLUGINS_REGISTRATION_GICP_FACTOR_H_

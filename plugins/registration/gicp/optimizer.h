// Gauss-Newton or Levenberg-Marquardt on SE(3) over the GICP factors
// (small_gicp's optimizers): linearize, solve (H + lambda I) d = -b, apply
// d = (w, v) on the left, T <- (Exp(w), v) T, until the step is below both
// epsilons.
#ifndef LOCFORGE_PLUGINS_REGISTRATION_GICP_OPTIMIZER_H_
#define LOCFORGE_PLUGINS_REGISTRATION_GICP_OPTIMIZER_H_

#include "factor.h"

namespace locforge::gicp {

struct OptimizerOptions {
  int max_iterations = 64;
  double rotation_epsilon = 1e-4;     // radians; converged when the step is below both
  double translation_epsilon = 1e-4;  // metres (registration/gicp: why so tight)
  bool levenberg_marquardt = false;   // else Gauss-Newton
  double lambda = 1e-6;               // damping (LM: initial value, adapted)
};

struct Outcome {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  bool converged = false;
  int iterations = 0;
  LinearSystem system;  // linearized at T: H is the information matrix
};

Eigen::Isometry3d ApplyLeft(const Vector6d& delta, const Eigen::Isometry3d& T);

Outcome Optimize(const GicpInputs& in, const Eigen::Isometry3d& initial, const FactorOptions& f,
                 const OptimizerOptions& o, int threads);

}  // namespace locforge::gicp

#endif  // LOCFORGE_PLUGINS_REGISTRATION_GICP_OPTIMIZER_H_

#include "optimizer.h"

#include <Eigen/Cholesky>

namespace locforge::gicp {

namespace {
constexpr uint64_t kMinInliers = 6;  // fewer cannot constrain 6 degrees of freedom

bool SmallStep(const Vector6d& d, const OptimizerOptions& o) {
  return d.head<3>().norm() < o.rotation_epsilon && d.tail<3>().norm() < o.translation_epsilon;
}

Vector6d Solve(const LinearSystem& s, double lambda) {
  return (s.H + lambda * Matrix6d::Identity()).ldlt().solve(-s.b);
}
}  // namespace

Eigen::Isometry3d ApplyLeft(const Vector6d& delta, const Eigen::Isometry3d& T) {
  Eigen::Isometry3d D = Eigen::Isometry3d::Identity();
  D.linear() = ExpSO3(delta.head<3>()).toRotationMatrix();
  D.translation() = delta.tail<3>();
  Eigen::Isometry3d out = D * T;
  // Re-orthonormalise so rounding does not accumulate over iterations.
  out.linear() = Eigen::Quaterniond(out.linear()).normalized().toRotationMatrix();
  return out;
}

Outcome Optimize(const GicpInputs& in, const Eigen::Isometry3d& initial, const FactorOptions& f,
                 const OptimizerOptions& o, int threads) {
  Outcome out;
  out.T = initial;
  std::vector<int> pairs(in.source->size(), -1);  // warm starts of the correspondence searches
  out.system = Linearize(in, out.T, f, threads, &pairs);
  double lambda = o.lambda;
  for (int it = 1; it <= o.max_iterations; ++it) {
    if (out.system.inliers < kMinInliers) return out;
    out.iterations = it;
    if (!o.levenberg_marquardt) {
      const Vector6d d = Solve(out.system, lambda);
      out.T = ApplyLeft(d, out.T);
      out.system = Linearize(in, out.T, f, threads, &pairs);
      if (SmallStep(d, o)) {
        out.converged = true;
        return out;
      }
      continue;
    }
    // LM: accept a step only when it lowers the cost; otherwise damp more.
    bool accepted = false;
    Vector6d d = Vector6d::Zero();
    for (int tries = 0; tries < 10 && !accepted; ++tries) {
      d = Solve(out.system, lambda);
      const Eigen::Isometry3d T = ApplyLeft(d, out.T);
      std::vector<int> tried = pairs;  // kept only if the step is
      LinearSystem s = Linearize(in, T, f, threads, &tried);
      if (s.inliers >= kMinInliers && s.cost <= out.system.cost) {
        out.T = T;
        out.system = std::move(s);
        pairs.swap(tried);
        lambda /= 10;
        accepted = true;
      } else {
        lambda *= 10;
      }
    }
    if (!accepted || SmallStep(d, o)) {
      out.converged = true;  // no step lowers the cost further: a minimum
      return out;
    }
  }
  return out;
}

}  // namespace locforge::gicp

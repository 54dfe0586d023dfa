// registration/gicp: our Generalized-ICP (Segal et al. 2009), Eigen + OpenMP,
// following small_gicp's split: preprocess (voxel grid, KD-tree, covariances)
// -> factor (correspondence, rejector, Mahalanobis cost, robust kernel)
// -> optimizer (Gauss-Newton / Levenberg-Marquardt on SE(3)).
#include <algorithm>
#include <memory>
#include <string>

#include "gicp/factor.h"
#include "gicp/kdtree.h"
#include "locforge/plugin.h"
#include "locforge/registration.h"
#include "gicp/optimizer.h"
#include "gicp/preprocess.h"

namespace locforge::gicp {
namespace {

struct GicpOptions {
  double voxel_size = 0;                     // Downsample both clouds first (metres); 0 = off.
  double max_correspondence_distance = 1.0;  // Pairs farther apart are rejected (metres).
  int max_iterations = 64;                   // Optimizer iterations at most.
  double rotation_epsilon = 2e-3;            // Converged when a step rotates less (radians)...
  double translation_epsilon = 1e-3;         // ...and translates less (metres).
  int k_neighbors = 20;                      // Neighbours per covariance.
  double covariance_epsilon = 1e-3;          // Normal-direction eigenvalue of the plane prior.
  // none | huber | cauchy. Cauchy by default: points without a true
  // counterpart (people walking through an indoor scan) otherwise pull every
  // registration toward zero motion (figures: plugins/common/lidar/README.md).
  std::string robust_kernel = "cauchy";
  double kernel_width = 0.25;                // In units of the Mahalanobis distance.
  std::string optimizer = "gauss_newton";    // gauss_newton | levenberg_marquardt.
  double lambda = 1e-6;                      // Damping (LM: initial value).

  static void Declare(ParamSchema<GicpOptions>& s) {
    s.Add("voxel_size", &GicpOptions::voxel_size, "Voxel downsampling of both clouds, metres; 0 = off")
        .Range(0, 100);
    s.Add("max_correspondence_distance", &GicpOptions::max_correspondence_distance,
          "Correspondences farther apart are rejected, metres")
        .Range(1e-6, 1e4);
    s.Add("max_iterations", &GicpOptions::max_iterations, "Optimizer iterations at most")
        .Range(1, 10000);
    s.Add("rotation_epsilon", &GicpOptions::rotation_epsilon,
          "Converged when a step rotates less than this (radians) and...")
        .Range(0, 1);
    s.Add("translation_epsilon", &GicpOptions::translation_epsilon,
          "...translates less than this (metres)")
        .Range(0, 10);
    s.Add("k_neighbors", &GicpOptions::k_neighbors, "Neighbours used for each covariance")
        .Range(3, 200);
    s.Add("covariance_epsilon", &GicpOptions::covariance_epsilon,
          "Normal-direction eigenvalue of the plane-regularised covariances")
        .Range(1e-9, 1);
    s.Add("robust_kernel", &GicpOptions::robust_kernel, "Robust kernel on the Mahalanobis residual")
        .Choices({"none", "huber", "cauchy"});
    s.Add("kernel_width", &GicpOptions::kernel_width, "Robust kernel width (Mahalanobis units)")
        .Range(1e-9, 1e9);
    s.Add("optimizer", &GicpOptions::optimizer, "Optimizer on SE(3)")
        .Choices({"gauss_newton", "levenberg_marquardt"});
    s.Add("lambda", &GicpOptions::lambda, "Damping added to the normal equations").Range(0, 1e6);
  }
};

RobustKernel KernelOf(const std::string& name) {
  if (name == "huber") return RobustKernel::kHuber;
  if (name == "cauchy") return RobustKernel::kCauchy;
  return RobustKernel::kNone;
}

class Gicp : public RegistrationComponent<Gicp, GicpOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"registration", "gicp",
            "Generalized-ICP (Segal 2009), Eigen + OpenMP, small_gicp-style", {}, {}};
    meta.version = "1.1.0";
    return meta;
  }
  explicit Gicp(GicpOptions o) : RegistrationComponent(std::move(o)) {}

  RegistrationResult Align(const PointCloud& source_cloud, const PointCloud& target_cloud,
                           const Pose& initial, int threads) const override {
    const GicpOptions& o = options();
    // The serial steps (voxel grid, tree build) of the two clouds run side by side.
    Points source, target;
#pragma omp parallel sections num_threads(std::min(threads, 2))
    {
#pragma omp section
      source = VoxelDownsample(ToPoints(source_cloud), o.voxel_size);
#pragma omp section
      target = VoxelDownsample(ToPoints(target_cloud), o.voxel_size);
    }
    if (source.size() < 6 || target.size() < 6)
      throw InputError("registration/gicp: clouds need at least 6 points (source " +
                       std::to_string(source.size()) + ", target " +
                       std::to_string(target.size()) + ")");
    std::unique_ptr<KdTree> source_tree_ptr, target_tree_ptr;
#pragma omp parallel sections num_threads(std::min(threads, 2))
    {
#pragma omp section
      source_tree_ptr = std::make_unique<KdTree>(source);
#pragma omp section
      target_tree_ptr = std::make_unique<KdTree>(target);
    }
    const KdTree& source_tree = *source_tree_ptr;
    const KdTree& target_tree = *target_tree_ptr;
    const Covariances source_cov =
        EstimateCovariances(source, source_tree, o.k_neighbors, o.covariance_epsilon, threads);
    const Covariances target_cov =
        EstimateCovariances(target, target_tree, o.k_neighbors, o.covariance_epsilon, threads);

    const GicpInputs in{&source, &source_cov, &target, &target_cov, &target_tree};
    FactorOptions f;
    f.max_correspondence_distance = o.max_correspondence_distance;
    f.kernel = KernelOf(o.robust_kernel);
    f.kernel_width = o.kernel_width;
    OptimizerOptions opt;
    opt.max_iterations = o.max_iterations;
    opt.rotation_epsilon = o.rotation_epsilon;
    opt.translation_epsilon = o.translation_epsilon;
    opt.levenberg_marquardt = o.optimizer == "levenberg_marquardt";
    opt.lambda = o.lambda;
    Eigen::Isometry3d T0 = Eigen::Isometry3d::Identity();
    T0.linear() = initial.R();
    T0.translation() = initial.t;
    const Outcome out = Optimize(in, T0, f, opt, threads);

    RegistrationResult r;
    r.converged = out.converged;
    r.iterations = out.iterations;
    r.num_inliers = out.system.inliers;
    r.inlier_fraction = static_cast<double>(out.system.inliers) / static_cast<double>(source.size());
    r.final_error = out.system.inliers ? out.system.cost / static_cast<double>(out.system.inliers) : 0;
    r.T_target_source = Pose(Eigen::Quaterniond(out.T.linear()), out.T.translation());
    r.information = out.system.H;
    return r;
  }
};

}  // namespace
LOCFORGE_EXPORT_STAGE(AddGicp, Gicp)

}  // namespace locforge::gicp

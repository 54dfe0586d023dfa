// registration/gicp: our Generalized-ICP (Segal et al. 2009), Eigen + OpenMP,
// following small_gicp's split: preprocess (voxel grid, KD-tree, covariances)
// -> factor (correspondence, rejector, Mahalanobis cost, robust kernel)
// -> optimizer (Gauss-Newton / Levenberg-Marquardt on SE(3)).
#include <algorithm>
#include <memory>
#include <string>
#include <utility>

#include "gicp/cloud_cache.h"
#include "gicp/factor.h"
#include "gicp/kdtree.h"
#include "gicp/optimizer.h"
#include "gicp/preprocess.h"
#include "locforge/plugin.h"
#include "locforge/registration.h"

namespace locforge::registration {

using namespace ::locforge::gicp;  // the library this stage wires
namespace {

struct GicpOptions {
  double voxel_size = 0;                     // Downsample both clouds first (metres); 0 = off.
  double max_correspondence_distance = 1.0;  // Pairs farther apart are rejected (metres).
  int max_iterations = 64;                   // Optimizer iterations at most.
  // Converged when a step rotates less than rotation_epsilon (radians) and
  // translates less than translation_epsilon (metres). Tight on purpose: the
  // robust weights make the last iterations converge linearly, so a loose
  // stop leaves each registration short of its optimum on the side of its
  // guess, a bias that a SLAM chaining hundreds of them accumulates
  // (docs/results/slam.md).
  double rotation_epsilon = 1e-4;
  double translation_epsilon = 1e-4;
  int k_neighbors = 20;                      // Neighbours per covariance.
  double covariance_epsilon = 1e-3;          // Normal-direction eigenvalue of the plane prior.
  // none | huber | cauchy. Cauchy by default: points without a true
  // counterpart (people walking through an indoor scan) otherwise pull every
  // registration toward zero motion (figures: docs/results/slam-history.md).
  std::string robust_kernel = "cauchy";
  double kernel_width = 0.25;                // In units of the Mahalanobis distance.
  std::string optimizer = "gauss_newton";    // gauss_newton | levenberg_marquardt.
  double lambda = 1e-6;                      // Damping (LM: initial value).
  // Preprocessed clouds kept by this back-end instance (least recently used
  // dropped first), so registering a cloud again skips its downsampling,
  // KD-tree and covariances; 0 = off. An entry takes 12 bytes per input
  // point and ~130 per point kept (points, tree, covariances).
  int cache_clouds = 8;

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
    s.Add("cache_clouds", &GicpOptions::cache_clouds,
          "Preprocessed clouds kept for repeated registrations (LRU); 0 = off")
        .Range(0, 10000);
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
    meta.version = "1.5.0";
    return meta;
  }
  explicit Gicp(GicpOptions o)
      : RegistrationComponent(std::move(o)), cache_(static_cast<size_t>(options().cache_clouds)) {}

  RegistrationResult Align(const PointCloud& source_cloud, const PointCloud& target_cloud,
                           const Pose& initial, int threads) const override {
    const GicpOptions& o = options();
    const auto [source_ptr, target_ptr] = Prepare(source_cloud, target_cloud, threads);
    const PreprocessedCloud& source = *source_ptr;
    const PreprocessedCloud& target = *target_ptr;
    if (source.points.size() < 6 || target.points.size() < 6)
      throw InputError("registration/gicp: clouds need at least 6 points (source " +
                       std::to_string(source.points.size()) + ", target " +
                       std::to_string(target.points.size()) + ")");

    const GicpInputs in{&source.points, &source.covariances, &target.points, &target.covariances,
                        &target.tree, &target.neighbors};
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
    r.inlier_fraction = static_cast<double>(out.system.inliers) / static_cast<double>(source.points.size());
    r.final_error = out.system.inliers ? out.system.cost / static_cast<double>(out.system.inliers) : 0;
    r.T_target_source = Pose(Eigen::Quaterniond(out.T.linear()), out.T.translation());
    r.information = out.system.H;
    return r;
  }

 private:
  using Prepared = std::shared_ptr<const PreprocessedCloud>;

  // Both clouds preprocessed, from the cache when it holds them. Two fresh
  // clouds are preprocessed side by side, one per thread; a single one uses
  // all threads for its covariances. Same results for any thread count.
  std::pair<Prepared, Prepared> Prepare(const PointCloud& source_cloud, const PointCloud& target_cloud,
                                        int threads) const {
    const GicpOptions& o = options();
    const PreprocessOptions p{o.voxel_size, o.k_neighbors, o.covariance_epsilon};
    Prepared source = cache_.Find(source_cloud, p), target = cache_.Find(target_cloud, p);
    const auto make = [&](const PointCloud& cloud, int t) {
      return std::make_shared<const PreprocessedCloud>(Preprocess(cloud, p, t));
    };
    if (!source && !target && threads > 1) {
#pragma omp parallel sections num_threads(2)
      {
#pragma omp section
        source = make(source_cloud, 1);
#pragma omp section
        target = make(target_cloud, 1);
      }
      source = cache_.Insert(source_cloud, p, source);
      target = cache_.Insert(target_cloud, p, target);
    }
    if (!source) source = cache_.Insert(source_cloud, p, make(source_cloud, threads));
    if (!target) target = cache_.Insert(target_cloud, p, make(target_cloud, threads));
    return {source, target};
  }

  mutable CloudCache cache_;
};

}  // namespace
LOCFORGE_REGISTER_STAGE(Gicp)

}  // namespace locforge::registration

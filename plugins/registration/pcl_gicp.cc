// registration/pcl_gicp: PCL's GeneralizedIterativeClosestPoint. PCL types
// stay in this file; inliers, error and information are computed with our
// GICP factor at PCL's solution (same definitions as registration/gicp).
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/gicp.h>

#include "locforge/plugin.h"
#include "locforge/registration.h"
#include "pcl_common.h"

namespace locforge::registration {

using namespace ::locforge::pclreg;  // the library this stage wires
namespace {

using Gicp = WithIterations<pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>>;

class PclGicp : public RegistrationComponent<PclGicp, PclOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"registration", "pcl_gicp", "PCL Generalized-ICP", {}, {}};
    meta.version = "1.0.0";
    return meta;
  }
  explicit PclGicp(PclOptions o) : RegistrationComponent(std::move(o)) {}

  RegistrationResult Align(const PointCloud& source_cloud, const PointCloud& target_cloud,
                           const Pose& initial, int threads) const override {
    const PclOptions& o = options();
    const auto [source, target] = DownsampledClouds(source_cloud, target_cloud, o.voxel_size, "registration/pcl_gicp");
    Gicp g;
    g.setInputSource(ToPcl<pcl::PointXYZ>(source));
    g.setInputTarget(ToPcl<pcl::PointXYZ>(target));
    g.setMaxCorrespondenceDistance(o.max_correspondence_distance);
    g.setMaximumIterations(o.max_iterations);
    g.setTransformationEpsilon(o.transformation_epsilon);
    g.setCorrespondenceRandomness(o.k_neighbors);
    pcl::PointCloud<pcl::PointXYZ> aligned;
    g.align(aligned, initial.Matrix().cast<float>());
    const Eigen::Matrix4d T = g.getFinalTransformation().cast<double>();

    // Statistics at the solution with the same factor as registration/gicp.
    const gicp::KdTree source_tree(source), target_tree(target);
    const gicp::Covariances cs = gicp::EstimateCovariances(source, source_tree, o.k_neighbors, 1e-3, threads);
    const gicp::Covariances ct = gicp::EstimateCovariances(target, target_tree, o.k_neighbors, 1e-3, threads);
    const gicp::GicpInputs in{&source, &cs, &target, &ct, &target_tree};
    gicp::FactorOptions f;
    f.max_correspondence_distance = o.max_correspondence_distance;
    const gicp::LinearSystem s = gicp::Linearize(in, Eigen::Isometry3d(T), f, threads);
    return MakeResult(g.hasConverged(), g.iterations(), T, s, source.size());
  }
};

}  // namespace
LOCFORGE_REGISTER_STAGE(PclGicp)

}  // namespace locforge::registration

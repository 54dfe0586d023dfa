// registration/pcl_gicp: PCL's GeneralizedIterativeClosestPoint. PCL types
// stay in this file; inliers, error and information are computed with our
// GICP factor at PCL's solution (same definitions as registration/gicp).
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/gicp.h>

#include "gicp/factor.h"
#include "gicp/preprocess.h"
#include "locforge/plugin.h"
#include "locforge/registration.h"
#include "pcl_common.h"

namespace locforge::pclreg {
namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;

class Gicp : public pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> {
 public:
  int iterations() const { return nr_iterations_; }
};

Cloud::Ptr ToPcl(const gicp::Points& points) {
  Cloud::Ptr c(new Cloud);
  c->resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) (*c)[i].getVector3fMap() = points[i].cast<float>();
  return c;
}

class PclGicp : public RegistrationComponent<PclGicp, PclOptions> {
 public:
  static StageMeta Meta() {
    return {"registration", "pcl_gicp", "PCL Generalized-ICP", {}, {}};
  }
  explicit PclGicp(PclOptions o) : RegistrationComponent(std::move(o)) {}

  RegistrationResult Align(const PointCloud& source_cloud, const PointCloud& target_cloud,
                           const Pose& initial, int threads) const override {
    const PclOptions& o = options();
    const gicp::Points source = gicp::VoxelDownsample(gicp::ToPoints(source_cloud), o.voxel_size);
    const gicp::Points target = gicp::VoxelDownsample(gicp::ToPoints(target_cloud), o.voxel_size);
    if (source.size() < 6 || target.size() < 6)
      throw InputError("registration/pcl_gicp: clouds need at least 6 points");
    Gicp g;
    g.setInputSource(ToPcl(source));
    g.setInputTarget(ToPcl(target));
    g.setMaxCorrespondenceDistance(o.max_correspondence_distance);
    g.setMaximumIterations(o.max_iterations);
    g.setTransformationEpsilon(o.transformation_epsilon);
    g.setCorrespondenceRandomness(o.k_neighbors);
    Cloud aligned;
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
    RegistrationResult r;
    r.converged = g.hasConverged();
    r.iterations = g.iterations();
    r.num_inliers = s.inliers;
    r.inlier_fraction = static_cast<double>(s.inliers) / static_cast<double>(source.size());
    r.final_error = s.inliers ? s.cost / static_cast<double>(s.inliers) : 0;
    r.T_target_source = Pose::FromMatrix(T);
    r.information = s.H;
    return r;
  }
};

}  // namespace
}  // namespace locforge::pclreg

LOCFORGE_PLUGIN("registration_pcl_gicp", "1.0.0", "PCL Generalized-ICP back-end",
                locforge::pclreg::PclGicp)

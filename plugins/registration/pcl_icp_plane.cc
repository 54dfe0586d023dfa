// registration/icp_plane: PCL point-to-plane ICP
// (IterativeClosestPointWithNormals), normals by NormalEstimationOMP when the
// clouds carry none. PCL types stay in this file.
#include <pcl/features/normal_3d_omp.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>

#include "gicp/preprocess.h"
#include "locforge/plugin.h"
#include "locforge/registration.h"
#include "pcl_common.h"
#include "point_to_plane.h"

namespace locforge::pclreg {
namespace {

using Cloud = pcl::PointCloud<pcl::PointNormal>;

// Exposes the iteration count PCL keeps protected.
class Icp : public pcl::IterativeClosestPointWithNormals<pcl::PointNormal, pcl::PointNormal> {
 public:
  int iterations() const { return nr_iterations_; }
};

Cloud::Ptr ToPcl(const gicp::Points& points, const PointCloud& original, double voxel, int k,
                 int threads) {
  Cloud::Ptr c(new Cloud);
  c->resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    (*c)[i].getVector3fMap() = points[i].cast<float>();
  }
  if (original.has_normals() && voxel <= 0) {
    for (size_t i = 0; i < points.size(); ++i) (*c)[i].getNormalVector3fMap() = original.normals[i];
    return c;
  }
  pcl::NormalEstimationOMP<pcl::PointNormal, pcl::PointNormal> ne(threads);
  ne.setInputCloud(c);
  ne.setSearchMethod(pcl::search::KdTree<pcl::PointNormal>::Ptr(new pcl::search::KdTree<pcl::PointNormal>));
  ne.setKSearch(k);
  ne.compute(*c);  // fills normal_x/y/z and curvature, keeps xyz
  return c;
}

class IcpPlane : public RegistrationComponent<IcpPlane, PclOptions> {
 public:
  static StageMeta Meta() {
    return {"registration", "icp_plane", "PCL point-to-plane ICP (normals estimated if absent)",
            {}, {}};
  }
  explicit IcpPlane(PclOptions o) : RegistrationComponent(std::move(o)) {}

  RegistrationResult Align(const PointCloud& source_cloud, const PointCloud& target_cloud,
                           const Pose& initial, int threads) const override {
    const PclOptions& o = options();
    const gicp::Points source = gicp::VoxelDownsample(gicp::ToPoints(source_cloud), o.voxel_size);
    const gicp::Points target = gicp::VoxelDownsample(gicp::ToPoints(target_cloud), o.voxel_size);
    if (source.size() < 6 || target.size() < 6)
      throw InputError("registration/icp_plane: clouds need at least 6 points");
    const Cloud::Ptr src = ToPcl(source, source_cloud, o.voxel_size, o.k_neighbors, threads);
    const Cloud::Ptr tgt = ToPcl(target, target_cloud, o.voxel_size, o.k_neighbors, threads);
    Icp icp;
    icp.setInputSource(src);
    icp.setInputTarget(tgt);
    icp.setMaxCorrespondenceDistance(o.max_correspondence_distance);
    icp.setMaximumIterations(o.max_iterations);
    icp.setTransformationEpsilon(o.transformation_epsilon);
    Cloud aligned;
    icp.align(aligned, initial.Matrix().cast<float>());
    const Eigen::Matrix4d T = icp.getFinalTransformation().cast<double>();

    gicp::Points normals(target.size());
    for (size_t i = 0; i < target.size(); ++i) normals[i] = (*tgt)[i].getNormalVector3fMap().cast<double>();
    const gicp::KdTree tree(target);
    Eigen::Isometry3d iso(T);
    const gicp::LinearSystem s = gicp::PointToPlaneSystem(
        source, target, normals, tree, iso, o.max_correspondence_distance, threads);
    RegistrationResult r;
    r.converged = icp.hasConverged();
    r.iterations = icp.iterations();
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

LOCFORGE_PLUGIN("registration_icp_plane", "1.0.0", "PCL point-to-plane ICP back-end",
                locforge::pclreg::IcpPlane)

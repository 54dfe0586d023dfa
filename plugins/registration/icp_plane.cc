// registration/icp_plane: PCL point-to-plane ICP
// (IterativeClosestPointWithNormals), normals by NormalEstimationOMP when the
// clouds carry none. PCL types stay in this file.
#include <pcl/features/normal_3d_omp.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>

#include "locforge/plugin.h"
#include "locforge/registration.h"
#include "pcl_common.h"
#include "gicp/point_to_plane.h"

namespace locforge::registration {

using namespace ::locforge::pclreg;  // the library this stage wires
namespace {

using Cloud = pcl::PointCloud<pcl::PointNormal>;

using Icp = WithIterations<pcl::IterativeClosestPointWithNormals<pcl::PointNormal, pcl::PointNormal>>;

// Points with normals: the cloud's own (when not downsampled), else estimated.
Cloud::Ptr WithNormals(const gicp::Points& points, const PointCloud& original, double voxel, int k,
                       int threads) {
  Cloud::Ptr c = ToPcl<pcl::PointNormal>(points);
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
    StageMeta meta = {"registration", "icp_plane", "PCL point-to-plane ICP (normals estimated if absent)",
            {}, {}};
    meta.version = "1.0.0";
    return meta;
  }
  explicit IcpPlane(PclOptions o) : RegistrationComponent(std::move(o)) {}

  RegistrationResult Align(const PointCloud& source_cloud, const PointCloud& target_cloud,
                           const Pose& initial, int threads) const override {
    const PclOptions& o = options();
    const auto [source, target] = DownsampledClouds(source_cloud, target_cloud, o.voxel_size, "registration/icp_plane");
    const Cloud::Ptr src = WithNormals(source, source_cloud, o.voxel_size, o.k_neighbors, threads);
    const Cloud::Ptr tgt = WithNormals(target, target_cloud, o.voxel_size, o.k_neighbors, threads);
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
    return MakeResult(icp.hasConverged(), icp.iterations(), T, s, source.size());
  }
};

}  // namespace
LOCFORGE_REGISTER_STAGE(IcpPlane)

}  // namespace locforge::registration

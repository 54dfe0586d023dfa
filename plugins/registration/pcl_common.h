// What the two PCL back-ends share: options, the downsampled input clouds,
// conversion to PCL clouds, access to PCL's iteration count, and the result
// built from statistics computed with our own factors at PCL's solution, so
// all back-ends report inliers, error and information the same way.
#ifndef LOCFORGE_PLUGINS_REGISTRATION_PCL_COMMON_H_
#define LOCFORGE_PLUGINS_REGISTRATION_PCL_COMMON_H_

#include <pcl/point_cloud.h>

#include <utility>

#include "gicp/factor.h"
#include "gicp/preprocess.h"
#include "locforge/params.h"
#include "locforge/registration.h"

namespace locforge::pclreg {

struct PclOptions {
  double voxel_size = 0;                     // Downsample both clouds first (metres); 0 = off.
  double max_correspondence_distance = 1.0;  // Pairs farther apart are rejected (metres).
  int max_iterations = 64;                   // Iterations at most.
  double transformation_epsilon = 1e-6;      // Converged when the transform changes less.
  int k_neighbors = 20;                      // Neighbours per normal / covariance.

  static void Declare(ParamSchema<PclOptions>& s) {
    s.Add("voxel_size", &PclOptions::voxel_size, "Voxel downsampling of both clouds, metres; 0 = off")
        .Range(0, 100);
    s.Add("max_correspondence_distance", &PclOptions::max_correspondence_distance,
          "Correspondences farther apart are rejected, metres")
        .Range(1e-6, 1e4);
    s.Add("max_iterations", &PclOptions::max_iterations, "Iterations at most").Range(1, 10000);
    s.Add("transformation_epsilon", &PclOptions::transformation_epsilon,
          "Converged when the transform changes less than this (PCL's squared measure)")
        .Range(0, 1);
    s.Add("k_neighbors", &PclOptions::k_neighbors, "Neighbours per normal or covariance")
        .Range(3, 200);
  }
};

// Both clouds voxel-downsampled; InputError when either keeps fewer than 6 points.
inline std::pair<gicp::Points, gicp::Points> DownsampledClouds(const PointCloud& source, const PointCloud& target,
                                                               double voxel_size, const std::string& stage) {
  std::pair<gicp::Points, gicp::Points> out(gicp::VoxelDownsample(gicp::ToPoints(source), voxel_size),
                                            gicp::VoxelDownsample(gicp::ToPoints(target), voxel_size));
  if (out.first.size() < 6 || out.second.size() < 6)
    throw InputError(stage + ": clouds need at least 6 points");
  return out;
}

// A PCL cloud of points of type P with only xyz filled.
template <typename P>
typename pcl::PointCloud<P>::Ptr ToPcl(const gicp::Points& points) {
  typename pcl::PointCloud<P>::Ptr c(new pcl::PointCloud<P>);
  c->resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) (*c)[i].getVector3fMap() = points[i].cast<float>();
  return c;
}

// A PCL registration exposing the iteration count PCL keeps protected.
template <typename Registration>
class WithIterations : public Registration {
 public:
  int iterations() const { return this->nr_iterations_; }
};

// The result at PCL's solution T from our statistics `s` there.
inline RegistrationResult MakeResult(bool converged, int iterations, const Eigen::Matrix4d& T,
                                     const gicp::LinearSystem& s, size_t source_points) {
  RegistrationResult r;
  r.converged = converged;
  r.iterations = iterations;
  r.num_inliers = s.inliers;
  r.inlier_fraction = static_cast<double>(s.inliers) / static_cast<double>(source_points);
  r.final_error = s.inliers ? s.cost / static_cast<double>(s.inliers) : 0;
  r.T_target_source = Pose::FromMatrix(T);
  r.information = s.H;
  return r;
}

}  // namespace locforge::pclreg

#endif  // LOCFORGE_PLUGINS_REGISTRATION_PCL_COMMON_H_

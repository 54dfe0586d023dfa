// Point clouds of the LiDAR stages: locforge::PointCloud (xyz, optional
// per-point time) read and written with the SDK (locforge/pointcloud_io.h);
// here only what the stages add: non-finite returns dropped on read, voxel
// downsampling, rigid transform, and the map-crispness measure.
#ifndef LOCFORGE_PLUGINS_COMMON_LIDAR_CLOUD_H_
#define LOCFORGE_PLUGINS_COMMON_LIDAR_CLOUD_H_

#include <Eigen/Core>
#include <tuple>
#include <unordered_map>
#include <vector>

#include "locforge/fs.h"
#include "locforge/pointcloud_io.h"
#include "locforge/pose.h"
#include "locforge/registration.h"

namespace locforge::lidar {

// times: seconds after the record timestamp; empty when unknown.
using Cloud = locforge::PointCloud;

// A PCD/PLY scan (SDK reader) without its NaN / infinite returns (organised
// clouds mark missing returns so). Throws InputError naming the file and field.
Cloud ReadScan(const fs::path& path);

// One point (the centroid) per occupied voxel of side `voxel` (m), its time the mean of the voxel's.
Cloud VoxelDownsample(const Cloud& cloud, double voxel);
// VoxelDownsample of a cloud given in pieces (e.g. keyframes read one at a
// time): Add every piece in order, then Result() is VoxelDownsample of their
// concatenation, bit for bit (the same sums in the same order), while only
// the cells are held. Times are not kept.
class VoxelAccumulator {
 public:
  explicit VoxelAccumulator(double voxel) : inv_(1.0 / voxel) {}
  void Add(const Cloud& piece);
  Cloud Result() const;

 private:
  struct Cell {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int n = 0;
  };
  struct KeyHash {
    size_t operator()(const std::tuple<int, int, int>& k) const;
  };
  double inv_;
  std::unordered_map<std::tuple<int, int, int>, Cell, KeyHash> cells_;
};

// Applies T to every point.
void Transform(const Pose& T, Cloud* cloud);

// Crispness of an accumulated map: for every point with at least `k`
// neighbours within `radius`, the distance from the point to the least-squares
// plane of its k nearest neighbours (itself excluded; normal = eigenvector of
// the smallest eigenvalue of their covariance). A blurred map (walls seen
// twice, a few cm apart) has larger residuals than a crisp one.
struct PlaneResidualStats {
  size_t points = 0;      // points evaluated (enough neighbours)
  size_t skipped = 0;     // points with fewer than k neighbours within radius
  double mean = 0, median = 0, rmse = 0, p90 = 0;  // m
};
// `threads`: the same figures at any count. `stride`: evaluated at every
// stride-th point only (neighbours still from the whole map), a systematic
// sample of the same statistics at 1/stride of the cost.
PlaneResidualStats MapPlaneResidual(const Cloud& map, int k = 10, double radius = 0.5, int threads = 1,
                                    int stride = 1);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_COMMON_LIDAR_CLOUD_H_

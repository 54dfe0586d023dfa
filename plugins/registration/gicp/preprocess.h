// Preprocessing of our GICP: float cloud -> double points, voxel-grid
// downsampling, and per-point covariances from k nearest neighbours.
#ifndef LOCFORGE_PLUGINS_REGISTRATION_GICP_PREPROCESS_H_
#define LOCFORGE_PLUGINS_REGISTRATION_GICP_PREPROCESS_H_

#include <Eigen/Core>
#include <vector>

#include "kdtree.h"
#include "locforge/registration.h"

namespace locforge::gicp {

using Covariances = std::vector<Eigen::Matrix3d>;

Points ToPoints(const PointCloud& cloud);

// One point per occupied voxel of edge `voxel_size` (the centroid of its
// points), in order of first occurrence, so the output is deterministic.
// voxel_size <= 0 returns the input.
Points VoxelDownsample(const Points& points, double voxel_size);
Points VoxelDownsample(const PointCloud& cloud, double voxel_size);  // = of ToPoints(cloud)

// Covariance of each point's k-neighbourhood, regularised to a plane
// (Segal et al. 2009, GICP, Sec. III-B "plane-to-plane"): the eigenvalues
// become (1, 1, epsilon), so the Mahalanobis cost penalises distance along
// the local normal 1/epsilon times more than within the plane. Points with
// fewer than 3 neighbours get epsilon-free identity (point-to-point).
// Each point's covariance depends on nothing else: same for any thread count.
// The k nearest neighbours of every point (itself included), kept from the
// covariance searches: ids[i * k ...] and radius[i], the distance to the k-th
// (infinite when the cloud has at most k points). Every point strictly closer
// than radius[i] to point i is in its list: what lets factor.cc certify a
// nearest neighbour found by walking the lists (factor.h).
struct NeighborGraph {
  int k = 0;
  std::vector<int> ids;
  std::vector<double> radius;
};

Covariances EstimateCovariances(const Points& points, const KdTree& tree, int k, double epsilon,
                                int threads, NeighborGraph* graph = nullptr);

struct PreprocessOptions {
  double voxel_size = 0;  // 0 = no downsampling
  int k_neighbors = 20;
  double covariance_epsilon = 1e-3;
  bool operator==(const PreprocessOptions& o) const {
    return voxel_size == o.voxel_size && k_neighbors == o.k_neighbors &&
           covariance_epsilon == o.covariance_epsilon;
  }
};

// A cloud ready for GICP: downsampled points, their KD-tree and covariances.
struct PreprocessedCloud {
  Points points;
  KdTree tree;
  Covariances covariances;
  NeighborGraph neighbors;
};

// Deterministic: the same cloud and options give bit-identical results for
// any thread count.
PreprocessedCloud Preprocess(const PointCloud& cloud, const PreprocessOptions& o, int threads);

}  // namespace locforge::gicp

#endif  // LOCFORGE_PLUGINS_REGISTRATION_GICP_PREPROCESS_H_

// The 2D-3D correspondences of one query (image or rig), built from its
// matches to map images: each (camera, query keypoint, 3D point) once, however
// many map images observe that point and matched that keypoint, as COLMAP's
// registration does. Counted once per map image, a point seen by many map
// images would weigh RANSAC's inlier count toward itself: a look-alike shop
// front mapped from several images could then outvote the true place.
#ifndef LOCFORGE_PLUGINS_LOCALIZER_PNP_CORRESPONDENCES_H_
#define LOCFORGE_PLUGINS_LOCALIZER_PNP_CORRESPONDENCES_H_

#include <cstdint>
#include <set>
#include <tuple>
#include <vector>

#include "absolute_pose.h"

namespace locforge::localization {

class CorrespondenceSet {
 public:
  // Adds query keypoint `keypoint` of camera `camera` (at `normalized`) with 3D
  // point `point_id` (at `world`); false when that triple is already in.
  bool Add(int camera, int64_t keypoint, int64_t point_id, const Eigen::Vector2d& normalized,
           const Eigen::Vector3d& world,
           const Eigen::Matrix3d& world_covariance = Eigen::Matrix3d::Zero()) {
    if (!seen_.insert({camera, keypoint, point_id}).second) return false;
    Correspondence c;
    c.normalized = normalized;
    c.world = world;
    c.world_covariance = world_covariance;
    c.camera = camera;
    correspondences_.push_back(c);
    return true;
  }
  const std::vector<Correspondence>& correspondences() const { return correspondences_; }

 private:
  std::set<std::tuple<int, int64_t, int64_t>> seen_;
  std::vector<Correspondence> correspondences_;
};

}  // namespace locforge::localization

#endif  // LOCFORGE_PLUGINS_LOCALIZER_PNP_CORRESPONDENCES_H_

// How well the map knows each 3D point, from the geometry that triangulated
// it: the first-order covariance of a point seen by views with known poses
// (Hartley & Zisserman, 2nd ed., sec. 12.6 / 5.2.2). A point seen by two views
// at a small angle is known well across its rays and poorly along them; a
// query looking at it from elsewhere sees that depth error as pixel error.
#ifndef LOCFORGE_PLUGINS_LOCALIZER_PNP_POINT_UNCERTAINTY_H_
#define LOCFORGE_PLUGINS_LOCALIZER_PNP_POINT_UNCERTAINTY_H_

#include <Eigen/Core>
#include <vector>

#include "locforge/pose.h"

namespace locforge::localization {

struct MapView {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // camera centre, world
  double focal = 1;                                  // pixels per normalised unit
};

// Covariance of `point` triangulated from `views` (world units^2 per px^2 of
// observation noise): the inverse of sum_i (f_i / d_i)^2 (I - u_i u_i^T),
// u_i the unit ray and d_i the distance from view i. A direction no view
// constrains (one view; rays parallel) gets a large finite variance.
Eigen::Matrix3d TriangulationCovariance(const Eigen::Vector3d& point, const std::vector<MapView>& views);

// The 2x2 W with |W r|^2 = r^T (I + J S J^T)^-1 r for a reprojection error r
// (pixels) of a point with covariance S (as above) seen by a camera with
// focal `focal` at camera_from_world: J is the projection's Jacobian. The
// observation's own noise is the unit; the point's adds to it.
Eigen::Matrix2d ReprojectionWhitening(const Pose& camera_from_world, double focal,
                                      const Eigen::Vector3d& point, const Eigen::Matrix3d& covariance);

}  // namespace locforge::localization

#endif  // LOCFORGE_PLUGINS_LOCALIZER_PNP_POINT_UNCERTAINTY_H_

// Point-to-plane statistics at a solution (for back-ends whose library does
// not report them, e.g. PCL's ICP): inliers, cost and the Gauss-Newton
// information H = sum J^T J of the residual n^T (t - T s), with
// J = n^T [ [Ts]x, -I ] (left perturbation, tangent order rx ry rz tx ty tz).
#ifndef LOCFORGE_PLUGINS_REGISTRATION_GICP_POINT_TO_PLANE_H_
#define LOCFORGE_PLUGINS_REGISTRATION_GICP_POINT_TO_PLANE_H_

#include "gicp/factor.h"

namespace locforge::gicp {

LinearSystem PointToPlaneSystem(const Points& source, const Points& target,
                                const Points& target_normals, const KdTree& target_tree,
                                const Eigen::Isometry3d& T, double max_correspondence_distance,
                                int threads);

}  // namespace locforge::gicp

#endif  // LOCFORGE_PLUGINS_REGISTRATION_GICP_POINT_TO_PLANE_H_

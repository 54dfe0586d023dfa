// Absolute pose from 2D-3D correspondences: P3P (Grunert's solution as
// reviewed by Haralick et al. 1994), EPnP (Lepetit et al. 2009), both inside
// LO-RANSAC, and a Cauchy-robust Ceres refinement.
//
// Observations are bearing vectors on the normalised image plane (z = 1) of a
// camera mounted on a rig: T_camera_rig maps rig to camera. A single camera is
// a rig with T_camera_rig = identity, so every solver estimates T_rig_world.
// Pixel errors are measured as focal * (normalised error), which keeps the
// refinement independent of the camera model (camera.h Unproject removes the
// distortion once, up front).
#ifndef LOCFORGE_PLUGINS_LOCALIZER_PNP_ABSOLUTE_POSE_H_
#define LOCFORGE_PLUGINS_LOCALIZER_PNP_ABSOLUTE_POSE_H_

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "locforge/pose.h"

namespace locforge::localization {

struct Correspondence {
  Eigen::Vector2d normalized = Eigen::Vector2d::Zero();  // undistorted, z = 1 plane
  Eigen::Vector3d world = Eigen::Vector3d::Zero();
  int camera = 0;  // index into the rig's cameras
  // How well the map knows `world` (point_uncertainty.h: world units^2 per
  // px^2 of observation noise); zero: exactly. The refinement weighs each
  // residual by it; RANSAC's inlier test does not.
  Eigen::Matrix3d world_covariance = Eigen::Matrix3d::Zero();
};

struct RigCamera {
  Pose camera_from_rig;  // T_camera_rig
  double focal = 1;      // pixels per normalised unit (error scale)
};

// All poses of the minimal problem (up to 4), as T_camera_world. Needs three
// non-collinear points; returns none on degenerate input.
std::vector<Pose> SolveP3P(const std::vector<Eigen::Vector3d>& bearings,
                           const std::vector<Eigen::Vector3d>& points);

// EPnP on n >= 4 points of one camera (normalised coordinates); exact on
// noise-free non-degenerate data with n >= 6. Returns false when degenerate.
bool SolveEPnP(const std::vector<Eigen::Vector2d>& normalized,
               const std::vector<Eigen::Vector3d>& points, Pose* camera_from_world);

// Squared reprojection error in pixels of one correspondence (infinite when
// the point is behind the camera).
double SquaredReprojectionError(const Pose& rig_from_world, const RigCamera& camera,
                                const Correspondence& c);

struct RefineOptions {
  double cauchy_scale_px = 1.0;  // Cauchy loss scale, pixels
  // > 0: the final refinement's scale is at least this many times the inliers'
  // measured noise (per-axis sigma), so the inliers of a noisier image are not
  // down-weighted like outliers (2.385: the Cauchy loss's 95 %-efficiency
  // constant for Gaussian noise). 0: cauchy_scale_px alone.
  double noise_factor = 0.0;
  // Multiplies every point's world_covariance: the map's observation noise
  // relative to the query's (0: every point exact).
  double point_covariance_scale = 1.0;
  int max_iterations = 50;
  bool Check(std::string* why) const;
};

// Minimises the Cauchy-robustified reprojection error over T_rig_world
// (intrinsics and rig fixed), each residual whitened by its point's
// uncertainty as seen from the starting pose (ReprojectionWhitening).
// Returns false when Ceres reports no usable solution (the pose is left
// unchanged then).
bool RefinePose(const std::vector<Correspondence>& correspondences,
                const std::vector<RigCamera>& cameras, const RefineOptions& options,
                Pose* rig_from_world);

struct RansacOptions {
  double max_error_px = 12.0;     // inlier threshold, pixels
  double confidence = 0.9999;     // stop when this sure of the best model
  int min_iterations = 100;
  int max_iterations = 10000;
  int min_inliers = 10;           // fewer -> failure
  double min_inlier_ratio = 0.0;  // below -> failure
  uint64_t seed = 0;              // deterministic sampling
  RefineOptions refine;
  bool Check(std::string* why) const;
};

struct AbsolutePoseResult {
  bool success = false;
  std::string failure;  // why, when !success
  Pose rig_from_world;
  std::vector<char> inlier_mask;
  int num_inliers = 0;
  int iterations = 0;
  double mean_inlier_error_px = 0;
};

// LO-RANSAC: P3P on minimal samples drawn from one camera, scored over all
// correspondences (truncated squared error, MSAC); every new best model is
// locally optimised (EPnP + Ceres on its inliers, repeated while the inliers
// grow); the final model is refined on all its inliers.
AbsolutePoseResult EstimateAbsolutePose(const std::vector<Correspondence>& correspondences,
                                        const std::vector<RigCamera>& cameras,
                                        const RansacOptions& options);

}  // namespace locforge::localization

#endif  // LOCFORGE_PLUGINS_LOCALIZER_PNP_ABSOLUTE_POSE_H_

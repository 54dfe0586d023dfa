// A synthetic spline-BA problem with a known answer (for the tests and the
// benchmark): a platform drives arcs of an ellipse in a rectangular room
// whose walls, floor, ceiling and pillars carry 3D points; cameras on the platform with their own
// models, rates and clocks observe them with pixel noise. The initial state
// is what the LiDAR half would hand over: noisy platform trajectory,
// perturbed intrinsics and rotational extrinsics, perturbed points, image
// poses = noisy trajectory at the image timestamp x perturbed extrinsic.
#ifndef LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_SYNTHETIC_H_
#define LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_SYNTHETIC_H_

#include <cstdint>

#include "spline_ba.h"

namespace locforge::sfm {

struct SyntheticOptions {
  int sequences = 2;
  double duration_s = 16;          // per sequence
  double speed_mps = 1.0;          // mean platform speed
  // Cameras: even index = "industrial" (648x512, 2.5 Hz), odd = "phone"
  // (540x720, 1 Hz); models cycle PINHOLE, SIMPLE_RADIAL, OPENCV, RADIAL,
  // SIMPLE_PINHOLE. Yaws evenly spread, 10 deg up-tilt.
  int cameras = 3;
  double clock_offset_sigma_s = 0.005;  // per-camera clock offset of the timestamps
  double jitter_sigma_s = 0.001;        // per-image capture jitter
  double points_per_m2 = 2.0;           // wall point density
  double pixel_noise_px = 0.5;
  int min_track_length = 2;
  double max_depth_m = 40;              // observations only of points closer than this
  // LiDAR-like trajectory noise at 10 Hz: white + a smooth (sinusoidal) part.
  double lidar_white_m = 0.02, lidar_white_deg = 0.3;
  double lidar_smooth_m = 0.02, lidar_smooth_deg = 0.3;
  // Calibration perturbations.
  double focal_perturbation = 0.03;        // relative, random sign per camera
  double principal_point_perturbation_px = 2.0;
  double rotation_perturbation_deg = 1.5;  // random axis per camera
  double point_noise_m = 0.05;
  uint32_t seed = 7;
};

struct SyntheticScene {
  BAProblem truth;    // true values (trajectories: true body poses at the sample times)
  BAProblem initial;  // the starting state, same observations
  // True capture time of each image (the timestamp differs by clock offset + jitter).
  std::vector<double> capture_time_s;
};

SyntheticScene MakeSyntheticScene(const SyntheticOptions& options);

// Errors of an adjusted problem against the truth.
struct SceneErrors {
  double position_rms_m = 0;    // camera centres (T_world_camera.t), in the truth's world frame
  double rotation_rms_deg = 0;  // camera orientations
  // The same after the rigid (SE(3), no scale) alignment of the estimated
  // camera centres to the true ones (Umeyama): the error without the gauge,
  // which the BA can only take from the LiDAR trajectory.
  double aligned_position_rms_m = 0;
  double aligned_rotation_rms_deg = 0;
  // Similarity (Sim(3)) alignment of the centres: its scale - 1 and the
  // residual (a map too large or too small shows here, not in the shape).
  double similarity_scale_minus_1 = 0;
  double similarity_position_rms_m = 0;
  double focal_max_rel = 0;     // max over sensors of |f - f_true| / f_true (fx and fy)
  double extrinsic_rotation_max_deg = 0;  // max over sensors of the T_body_camera rotation error
  double trajectory_position_rms_m = 0;   // trajectory samples vs true body poses
};
SceneErrors CompareToTruth(const BAProblem& estimate, const BAProblem& truth);

// The tests' scene: the defaults above with clock offsets of 3 ms sigma ("a
// few ms"; with 5 ms the extrinsic rotations absorb part of the offsets,
// README: ~0.1 deg).
SyntheticOptions TestSceneOptions();

// The bundle adjuster's settings these synthetic scenes are sized for:
// denser knots (their trajectories turn faster than a wheeled platform
// does), looser image and LiDAR priors than the stage's defaults, no
// sequence alignment unless a test asks for it; 100 iterations at most.
SplineBAOptions SyntheticSceneBAOptions();

}  // namespace locforge::sfm

#endif  // LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_SYNTHETIC_H_

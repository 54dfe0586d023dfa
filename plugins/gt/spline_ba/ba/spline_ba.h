// Continuous-time spline bundle adjustment with auto-calibration: the
// numerical core of the paper's SfM refinement (Lee et al., CVPR 2021,
// "Large-scale Localization Datasets in Crowded Indoor Spaces", section 3.2).
//
// The stage gt/spline_ba (plugins/gt/spline_ba.cc, outer loop in
// ../outer_loop.h) declares SplineBAOptions as its parameters.
//
// Model: each platform trajectory is a uniform cumulative cubic B-spline in
// SE(3), T_world_body(t) (spline.h). Each camera (sensor) has intrinsics and
// an extrinsic T_body_camera whose rotation is optimised and whose
// translation stays at the CAD value. Each image has its own pose
// T_world_camera, tied to the spline at the image's own timestamp by the
// pose error e_i = Log(T_world_camera_i^-1 * T_world_body(t_i) * T_body_camera)
// (SE(3) tangent, rotation first), so asynchronous cameras are handled.
// Residuals: Cauchy-robust reprojection error of every observation, and the
// spline pose error of every image weighted by diag(1/sigma_r, 1/sigma_t).
//
// Pose directions (locforge::Pose T_a_b maps b into a): everything here is
// world-from-X (T_world_body, T_world_camera) or body-from-camera
// (T_body_camera). kapture/COLMAP store T_camera_world: invert on the way in.
#ifndef LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_SPLINE_BA_H_
#define LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_SPLINE_BA_H_

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "locforge/camera.h"
#include "locforge/params.h"
#include "locforge/pose.h"
#include "spline.h"

namespace locforge::sfm {

struct BAProblem {
  // A platform trajectory: the initial (LiDAR) poses of the body at sample
  // times. After RunSplineBA the samples hold the fitted spline evaluated at
  // the same times.
  struct Trajectory {
    std::vector<double> times_s;       // increasing, seconds (any origin)
    std::vector<Pose> T_world_body;    // world-from-body, one per time
  };
  // A camera: intrinsics (COLMAP models SIMPLE_PINHOLE, PINHOLE,
  // SIMPLE_RADIAL, RADIAL, OPENCV) and the body-from-camera extrinsic.
  struct Sensor {
    Camera camera;
    Pose T_body_camera;                // body-from-camera; translation is never changed
    bool calibrate_intrinsics = true;  // and SplineBAOptions::calibrate_intrinsics
    bool calibrate_rotation = true;    // and SplineBAOptions::calibrate_rotations
    // Clock offset of the sensor's timestamps: its images are tied to the
    // spline at time_s + time_offset_s. Estimated (and written back) with
    // SplineBAOptions::estimate_time_offsets, else used as given.
    double time_offset_s = 0;
  };
  struct Image {
    int trajectory = -1;  // index into trajectories (-1: no spline prior for this image)
    int sensor = 0;       // index into sensors
    double time_s = 0;    // the image's own timestamp, same clock/origin as its trajectory
    Pose T_world_camera;  // world-from-camera; initial value, the adjusted one is written back
    std::string name;
  };
  struct Point {
    Eigen::Vector3d xyz = Eigen::Vector3d::Zero();  // world frame
  };
  struct Observation {
    int image = 0;
    int point = 0;
    Eigen::Vector2d xy = Eigen::Vector2d::Zero();  // pixels, pixel centre at +0.5 (COLMAP)
  };
  std::vector<Trajectory> trajectories;
  std::vector<Sensor> sensors;
  std::vector<Image> images;
  std::vector<Point> points;
  std::vector<Observation> observations;
  // With align_trajectories: the reference trajectory (the one that keeps the
  // LiDAR frame) is outside this problem, so every trajectory gets an
  // alignment (a block of a larger problem, blocked_ba.h).
  bool reference_outside = false;
  // Optional start of each trajectory's adjusted state (a block's previous
  // pass, blocked_ba.h): its spline, used when its knots are those the fit to
  // the samples would choose, and its alignment. Empty: fitted / identity.
  std::vector<SE3Spline> start_splines;
  std::vector<Pose> start_alignments;
  // A quadratic cost on a point, 0.5 |S (x - x0) + c|^2: what the
  // observations of images outside this problem (a neighbouring block's,
  // held) say about it to first order (blocked_ba.h).
  struct PointSummary {
    int point = -1;
    Eigen::Vector3d x0 = Eigen::Vector3d::Zero();
    Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
  };
  std::vector<PointSummary> point_summaries;

  // "" when every index is in range and every camera model is supported,
  // else the first problem found.
  std::string Validate() const;
};

// The options of the bundle adjuster. Their defaults are those of the stage
// gt/spline_ba, which declares each of them in place (ParamSchema nested
// members, rotations in degrees there); the reasons behind the values and
// their measured effects are in docs/results/ground-truth-history.md.
struct SplineBAOptions {
  // Spacing of the spline knots (control poses), seconds. Several images per
  // knot: a wheeled platform moves smoothly, the images' visual noise does not.
  double knot_spacing_s = 0.3;
  // Tie each image to its trajectory's spline (off: plain bundle adjustment
  // of free image poses; gauge then fixed as described at fix_gauge).
  bool use_spline_prior = true;
  // Optimise the intrinsics (all parameters of the model, see
  // refine_principal_point and fix_aspect_ratio) of the sensors that allow it.
  bool calibrate_intrinsics = true;
  bool refine_principal_point = true;
  // Keep fy / fx of the two-focal models (PINHOLE, OPENCV) at its initial
  // value: fx and fy move together. The pixel aspect ratio comes from the
  // sensor's pixel pitch (data sheet), and a platform moving in a plane
  // leaves the vertical scale of the scene, hence fy, nearly unobservable.
  bool fix_aspect_ratio = true;
  // Optimise the rotation of T_body_camera (only with use_spline_prior; the
  // translation is always the CAD value, as in the paper).
  bool calibrate_rotations = true;
  // Standard deviations of the spline pose error e_i (rotation part in
  // radians, translation part in metres): what an image may leave its spline
  // by (capture jitter, clock offsets: a few ms of motion).
  double prior_sigma_rotation_rad = DegreesToRadians(0.115);
  double prior_sigma_translation_m = 0.003;
  // Estimate one clock offset per sensor (Sensor::time_offset_s), bounded
  // by +-max_time_offset_s (< knot_spacing_s). Off by default: the paper
  // handles asynchronous cameras through each image's own timestamp only;
  // constant per-camera offsets then bias the extrinsic rotations.
  bool estimate_time_offsets = false;
  double max_time_offset_s = 0.05;
  // With estimate_time_offsets: hold the mean of the offsets at 0 (the
  // LiDAR clock, which the splines' samples use, is the reference on
  // average). A common offset of all cameras is otherwise held only by the
  // loose trajectory prior, and it trades against a common rotation of all
  // cameras about the turn axis: a platform turning at a mean yaw rate w
  // makes a common offset d look like a yaw of w * d.
  bool zero_mean_time_offsets = true;
  // Gauge with spline priors: a weak prior of every spline to its initial
  // (LiDAR) samples keeps the solution in the LiDAR map frame (6 DoF; the
  // metric scale comes from the fixed CAD translations); it holds the
  // LiDAR's low-frequency drift too. 0 for either sigma disables it; the
  // first control pose of trajectory 0 is then held fixed.
  double trajectory_prior_sigma_rotation_rad = DegreesToRadians(0.2);
  double trajectory_prior_sigma_translation_m = 0.03;
  // Let every trajectory but the first move rigidly as a whole against its
  // LiDAR samples: the prior above then compares each spline with its
  // samples after a per-trajectory alignment G_t (6 DoF, estimated), so the
  // images, not the LiDAR, place the sequences relative to each other. The
  // LiDAR merge of sequences is the least accurate part of the LiDAR poses,
  // and the extrinsic rotations, shared by all sequences, would otherwise
  // absorb it. Needs the trajectory prior (Check); the first trajectory with
  // images keeps the LiDAR map frame. A weak prior (sigmas below) keeps the
  // alignment of a sequence that no image connects to the others at the
  // LiDAR merge. Without spline priors there is nothing to align: ignored.
  bool align_trajectories = true;
  double alignment_sigma_rotation_rad = DegreesToRadians(3.0);
  double alignment_sigma_translation_m = 1.0;
  // Let each trajectory's LiDAR samples be scaled by its own factor exp(s_t)
  // (about the LiDAR world origin) before the trajectory prior compares
  // them with its spline, the mean of the log-factors held at 0. The
  // images (which all sequences share) then set the sequences' relative
  // scales, and the map keeps the LiDAR's mean scale: per-sequence scale
  // errors of the LiDAR half (a wheel radius off leaking through the
  // odometry edges) stop bending the map. Needs the trajectory prior. A weak
  // prior (sigma below) keeps the scale of an unconnected sequence at 1.
  bool scale_trajectories = false;
  double trajectory_scale_sigma = 0.01;  // of each log-factor (1 %)
  // Wheeled-base kinematics: in the middle of every spline segment the body
  // moves along its x axis, i.e. its body-frame velocity has no lateral (y)
  // part, within this std (m/s; 0: off). Needs the body origin at the centre
  // of the wheel axle, x forward (a differential-drive base such as the
  // simulator's). It holds each trajectory's heading to its direction of
  // travel, which the images measure to a few millimetres; without it only
  // the loose LiDAR rotation prior holds the common rotation of all cameras
  // against the body, and a LiDAR heading bias goes into every camera rotation.
  double nonholonomic_sigma_mps = 0;
  // Gauge without spline priors (plain BA): the pose of the first image with
  // an observation is held fixed and, for the scale, the largest coordinate of
  // the translation of the image farthest from it (as COLMAP fixes one
  // coordinate of the second image).
  bool fix_gauge = true;
  // Cauchy loss scale of the reprojection residuals, pixels.
  double cauchy_scale_px = 2.0;
  bool refine_points = true;
  int max_iterations = 50;
  double function_tolerance = 1e-6;
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-8;
  // Linear solver: "auto" (SPARSE_SCHUR up to sparse_schur_max_images
  // images, else ITERATIVE_SCHUR with SCHUR_JACOBI), "sparse_schur",
  // "iterative_schur". The inexact steps of ITERATIVE_SCHUR barely move the
  // weakly held directions (the common rotation of all cameras against the
  // body, under a loose trajectory prior) and Ceres then stops on the
  // function tolerance, hence SPARSE_SCHUR while it fits in memory.
  // "dense_schur": the reduced camera system as one dense matrix (LAPACK),
  // for problems of a few hundred images.
  std::string linear_solver = "auto";
  // Sparse Cholesky of SPARSE_SCHUR: "suite_sparse" (CHOLMOD, supernodal on
  // the system's BLAS) or "eigen_sparse" (Eigen's simplicial LDLT, no BLAS).
  std::string sparse_library = "suite_sparse";
  int sparse_schur_max_images = 2000;
  // Forcing sequence of the inexact (ITERATIVE_SCHUR) Newton steps (Ceres'
  // eta, its default 0.1): the conjugate gradients stop at this relative
  // residual.
  double iterative_eta = 0.001;
  // parallel_schur: the reduced system factorised in tiles of this size on
  // every thread (tiled_cholesky.h) where that costs at most
  // parallel_schur_tile_flop_ratio times CHOLMOD's operations (a system
  // dense enough, as a floor's is); else, and with 0, by CHOLMOD (one thread
  // on Debian's ATLAS), a rejected step's retry computed beside it.
  int parallel_schur_tile = 128;
  double parallel_schur_tile_flop_ratio = 2;
  // Ceres threads of this solve only (no process-wide state is touched).
  int num_threads = 1;
  bool verbose = false;  // Ceres per-iteration log to stdout
  // Polled after every Ceres iteration: true stops the solve (result.cancelled,
  // nothing written back). A long solve must answer Ctrl-C / SIGTERM.
  std::function<bool()> cancelled;

  bool Check() const { return CheckMessage().empty(); }
  // "" or the first invalid field, or combination, with the reason.
  std::string CheckMessage() const;
};

struct SplineBAResult {
  bool converged = false;  // Ceres reported convergence (not just the iteration limit)
  bool usable = false;     // Ceres produced a usable solution (the problem was written back)
  bool cancelled = false;  // options.cancelled stopped the solve
  int iterations = 0;
  double initial_cost = 0, final_cost = 0;  // Ceres costs (robustified, 0.5 * sum)
  double initial_mean_reproj_px = 0, final_mean_reproj_px = 0;  // plain (non-robust) mean
  int num_observations = 0;  // reprojection residuals used (in front of their camera)
  int num_prior_residuals = 0;
  int num_parameters = 0;    // tangent-space size of the variable blocks
  double seconds = 0;        // wall time of RunSplineBA
  std::string message;       // Ceres' message, or why nothing was done
  // The fitted spline of each trajectory (empty without spline priors).
  std::vector<SE3Spline> splines;
  // With align_trajectories: the estimated alignment G_t of each trajectory
  // (world-from-LiDAR-world; identity for the reference and unused ones).
  std::vector<Pose> trajectory_alignments;
  // With scale_trajectories: the estimated scale exp(s_t) of each
  // trajectory's LiDAR samples (1 for unused ones).
  std::vector<double> trajectory_scales;
};

// Adjusts `problem` in place: images' T_world_camera, sensors' intrinsics and
// T_body_camera rotation, points, and the trajectories' samples. Invalid
// options or problem -> result.message says why and nothing changes.
SplineBAResult RunSplineBA(const SplineBAOptions& options, BAProblem* problem);

// Whether observation o's point lies in front of its camera (RunSplineBA
// leaves the others out); *xy (optional) receives its projection.
bool InFront(const BAProblem& problem, const BAProblem::Observation& o, Eigen::Vector2d* xy = nullptr);

// Mean reprojection error (pixels) over the observations in front of their
// camera; *count (optional) receives their number.
double MeanReprojectionError(const BAProblem& problem, int* count = nullptr);

// Per-sensor mean reprojection error and observation count.
struct SensorStats {
  int observations = 0;
  double mean_reproj_px = 0;
};
std::vector<SensorStats> PerSensorStats(const BAProblem& problem);

}  // namespace locforge::sfm

#endif  // LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_SPLINE_BA_H_

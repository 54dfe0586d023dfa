// Stages of the plugin `sfm_gt` (the SfM half of the ground-truth pipeline,
// issue 8, paper section 3.2): calib/perturb, gt/images, gt/spline_ba,
// eval/calibration. Each declares its parameters once.
#ifndef LOCFORGE_PLUGINS_SFM_GT_STAGES_H_
#define LOCFORGE_PLUGINS_SFM_GT_STAGES_H_

#include <string>
#include <vector>

#include "locforge/plugin.h"

namespace locforge::sfm_gt {

// ------------------------------------------------------------ calib/perturb
struct PerturbOptions {
  double focal_percent = 3.0;       // Every focal length scaled by 1 +- this/100 (random sign).
  double rotation_deg = 1.5;        // Every camera rotated by this angle about a random axis.
  double principal_point_px = 0.0;  // Principal point moved by up to this in x and y.
  int seed = 0;                     // Signs, axes and offsets.
  static void Declare(ParamSchema<PerturbOptions>& s) {
    s.Add("focal_percent", &PerturbOptions::focal_percent, "focal lengths scaled by 1 +- this % (random sign)").Range(0, 50);
    s.Add("rotation_deg", &PerturbOptions::rotation_deg, "camera rotations (rigs.txt) turned by this angle about a random axis").Range(0, 30);
    s.Add("principal_point_px", &PerturbOptions::principal_point_px, "principal points moved by up to this (px)").Range(0, 1000);
    s.Add("seed", &PerturbOptions::seed, "random seed (signs, axes, offsets)").Min(0);
  }
};

class PerturbStage : public Stage<PerturbOptions> {
 public:
  static StageMeta Meta() {
    return {"calib", "perturb",
            "Intrinsics and camera rotations (rigs.txt) moved away from their values by fixed "
            "amounts (deterministic); camera poses recomputed with the moved extrinsics",
            {{"poses", "kapture.trajectories", "sensors.txt, rigs.txt, trajectories.txt (e.g. slam/pose_graph)"}},
            {{"trajectories", "kapture.trajectories", "perturbed sensors/rigs, camera poses; perturbation.txt"}}};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

// --------------------------------------------------------------- gt/images
struct ImagesOptions {
  std::string dataset;  // The recording (records_camera.txt + images).
  static void Declare(ParamSchema<ImagesOptions>& s) {
    s.Add("dataset", &ImagesOptions::dataset, "kapture recording with records_camera.txt and the images").Path().Required();
  }
};

class ImagesStage : public Stage<ImagesOptions> {
 public:
  static StageMeta Meta() {
    return {"gt", "images",
            "The images of a recording (records_camera.txt, images hard-linked) with the sensors, "
            "rigs and poses of another node (e.g. the LiDAR half), as one kapture dataset",
            {{"poses", "kapture.trajectories", "sensors.txt, rigs.txt, trajectories.txt"}},
            {{"dataset", "kapture.dataset", "cameras, poses, records_camera.txt, records_data/"}}};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

// ------------------------------------------------------------- gt/spline_ba
struct SplineBAStageOptions {
  int rounds = 6;  // Most rounds of triangulation + bundle adjustment.
  // COLMAP filter_max_reproj_error of round i (px); the last value repeats.
  std::vector<double> filter_max_reproj_error = {16, 8, 4, 2};
  // Spline knot spacing (s). 0.3 s averages ~6 images per knot: at 0.1 s
  // (about one control pose per 2 images) the splines followed each image's
  // visual noise (heights wobbling 0.5 cm from sample to sample on `small`)
  // while the true motion of a wheeled platform is smooth (a 0.3 s spline
  // fits the simulator's true trajectories within 0.2 mm). README "Knots".
  double knot_spacing_s = 0.3;
  bool use_spline_prior = true;         // Spline pose residuals (false: plain BA).
  bool calibrate_intrinsics = true;     // Optimise focal, principal point, distortion.
  bool calibrate_rotations = true;      // Optimise the rotation of every T_body_camera.
  double prior_sigma_rotation_deg = 0.115;  // Spline pose residual sigma, rotation (absorbs clock offsets).
  // Spline pose residual sigma, translation: what an image may leave its
  // spline by (capture jitter: 2 ms at 1 m/s is 2 mm). At 1 cm each image
  // followed its own visual noise (0.45 cm RMS in height on `small`).
  double prior_sigma_translation_m = 0.003;
  // Each spline to its initial (LiDAR) poses, per LiDAR sample. 3 cm / 0.2 deg
  // hold the LiDAR's low-frequency drift (2 cm RMS on `small`); 0.2 m / 2 deg
  // let the reprojection error remove it on `small` (0.85 cm) but let scale and
  // focal drift on `tiny` (one 8 s sequence). README "Why the positions stayed".
  double trajectory_prior_sigma_rotation_deg = 0.2;  // rotation (0: off)
  double trajectory_prior_sigma_translation_m = 0.03;  // translation (0: off)
  // Let each sequence but the first move rigidly against its LiDAR poses:
  // the images, not the LiDAR merge, place the sequences relative to each
  // other (ba/spline_ba.h; README "Sequence alignment"). Weak prior of each
  // alignment to the LiDAR merge (keeps an unconnected sequence where it is).
  bool align_trajectories = true;
  double alignment_sigma_rotation_deg = 3.0;
  double alignment_sigma_translation_m = 1.0;
  // Let each sequence's LiDAR poses also be scaled (mean log-scale held at
  // 0): the images set the sequences' relative scales (ba/spline_ba.h
  // scale_trajectories; README "Scale").
  bool scale_sequences = false;
  // Wheeled-base kinematics: std of the spline's sideways body velocity
  // (m/s; 0: off). For a differential-drive base whose rig origin is the
  // wheel axle's centre, x forward (ba/spline_ba.h nonholonomic_sigma_mps;
  // README "Session 8").
  double nonholonomic_sigma_mps = 0;
  bool refine_principal_point = true;   // With calibrate_intrinsics: also the principal point.
  bool fix_aspect_ratio = true;         // With calibrate_intrinsics: keep fy / fx (fx, fy move together).
  double cauchy_scale_px = 2.0;         // Cauchy loss scale of reprojection residuals.
  bool estimate_time_offsets = false;   // One clock offset per camera (not in the paper; README).
  double max_time_offset_s = 0.05;      // Bound of each estimated clock offset (s, < knot_spacing_s).
  bool zero_mean_time_offsets = true;   // Hold the mean clock offset at 0 (the LiDAR clock; ba/spline_ba.h).
  int max_iterations = 50;              // Solver iterations per round.
  // Linear solver of the BA: auto = sparse_schur up to sparse_schur_max_images
  // images, else iterative_schur (plugins/sfm_gt/ba/spline_ba.h).
  std::string linear_solver = "auto";
  int sparse_schur_max_images = 2000;
  double iterative_eta = 0.001;         // Relative residual of the conjugate gradients (iterative_schur).
  double pose_tolerance_m = 0.0005;     // Converged when the RMS camera-centre change of a round is below...
  double rotation_tolerance_deg = 0.005;  // ...and the RMS camera rotation change is below...
  double reproj_tolerance_px = 0.02;    // ...and the mean reprojection error changed less than this.
  double seconds_per_unit = 1e-6;       // Timestamp unit of the dataset (s).
  double sequence_gap_s = 2.0;          // Rig poses further apart start a new trajectory.
  std::string rig = "rig";              // Device id of the platform poses in trajectories.txt.
  std::string keypoints_type;           // Empty: the only one of the features.
  int min_num_matches = 15;             // COLMAP Mapper.min_num_matches.
  double timeout_s = 0;                 // Kill colmap after this long (0: never).
  static void Declare(ParamSchema<SplineBAStageOptions>& s) {
    using O = SplineBAStageOptions;
    s.Add("rounds", &O::rounds, "most rounds of triangulation + bundle adjustment").Range(1, 50);
    s.Add("filter_max_reproj_error", &O::filter_max_reproj_error,
          "COLMAP filter_max_reproj_error per round (px), lowered round by round; the last repeats");
    s.Add("knot_spacing_s", &O::knot_spacing_s, "cubic B-spline knot spacing (s)").Range(1e-3, 100);
    s.Add("use_spline_prior", &O::use_spline_prior, "spline pose residuals at each image's timestamp (false: plain BA)");
    s.Add("calibrate_intrinsics", &O::calibrate_intrinsics, "optimise the intrinsics of every camera");
    s.Add("calibrate_rotations", &O::calibrate_rotations, "optimise the rotation of every camera extrinsic");
    s.Add("prior_sigma_rotation_deg", &O::prior_sigma_rotation_deg, "spline pose residual sigma, rotation (deg)").Min(1e-6);
    s.Add("prior_sigma_translation_m", &O::prior_sigma_translation_m, "spline pose residual sigma, translation (m)").Min(1e-9);
    s.Add("trajectory_prior_sigma_rotation_deg", &O::trajectory_prior_sigma_rotation_deg,
          "prior of each spline to its initial (LiDAR) poses, rotation sigma (deg; 0: off)").Min(0);
    s.Add("trajectory_prior_sigma_translation_m", &O::trajectory_prior_sigma_translation_m,
          "prior of each spline to its initial (LiDAR) poses, translation sigma (m; 0: off)").Min(0);
    s.Add("scale_sequences", &O::scale_sequences,
          "scale each sequence's LiDAR poses too, their mean log-scale held at 0 (the images set relative scales)");
    s.Add("nonholonomic_sigma_mps", &O::nonholonomic_sigma_mps,
          "wheeled base, rig origin at the wheel axle centre, x forward: std of the spline's sideways velocity "
          "(m/s; 0: off)").Min(0);
    s.Add("align_trajectories", &O::align_trajectories,
          "estimate a rigid correction of each sequence's LiDAR poses but the first (the images place the sequences)");
    s.Add("alignment_sigma_rotation_deg", &O::alignment_sigma_rotation_deg,
          "align_trajectories: prior of each correction to the LiDAR merge, rotation sigma (deg)").Min(1e-6);
    s.Add("alignment_sigma_translation_m", &O::alignment_sigma_translation_m,
          "align_trajectories: prior of each correction to the LiDAR merge, translation sigma (m)").Min(1e-9);
    s.Add("refine_principal_point", &O::refine_principal_point, "with calibrate_intrinsics: also the principal points");
    s.Add("fix_aspect_ratio", &O::fix_aspect_ratio,
          "with calibrate_intrinsics: keep fy / fx of PINHOLE / OPENCV cameras (planar motion leaves fy nearly unobservable)");
    s.Add("cauchy_scale_px", &O::cauchy_scale_px, "Cauchy loss scale of reprojection residuals (px)").Min(1e-3);
    s.Add("estimate_time_offsets", &O::estimate_time_offsets,
          "estimate one clock offset per camera (image i tied to the spline at t_i + offset); time_offsets.csv");
    s.Add("max_time_offset_s", &O::max_time_offset_s, "bound of each estimated clock offset (s; < knot_spacing_s)").Min(1e-6);
    s.Add("zero_mean_time_offsets", &O::zero_mean_time_offsets,
          "with estimate_time_offsets: hold the mean offset at 0 (a common offset looks like a common camera yaw)");
    s.Add("max_iterations", &O::max_iterations, "solver iterations per round").Range(1, 10000);
    s.Add("linear_solver", &O::linear_solver,
          "BA linear solver: auto (sparse_schur up to sparse_schur_max_images images), sparse_schur, iterative_schur")
        .Choices({"auto", "sparse_schur", "iterative_schur"});
    s.Add("sparse_schur_max_images", &O::sparse_schur_max_images, "auto: the most images solved with sparse_schur").Min(0);
    s.Add("iterative_eta", &O::iterative_eta, "iterative_schur: relative residual of the conjugate gradients").Range(1e-9, 0.999);
    s.Add("pose_tolerance_m", &O::pose_tolerance_m, "convergence: RMS camera-centre change of a round (m)").Min(0);
    s.Add("rotation_tolerance_deg", &O::rotation_tolerance_deg, "convergence: RMS camera rotation change of a round (deg)").Min(0);
    s.Add("reproj_tolerance_px", &O::reproj_tolerance_px, "convergence: change of the mean reprojection error (px)").Min(0);
    s.Add("seconds_per_unit", &O::seconds_per_unit, "timestamp unit (s)").Range(1e-12, 1e6);
    s.Add("sequence_gap_s", &O::sequence_gap_s, "a gap this long between rig poses starts a new trajectory (s)").Min(0);
    s.Add("rig", &O::rig, "device id of the platform poses in trajectories.txt");
    s.Add("keypoints_type", &O::keypoints_type, "keypoints type; empty = the only one");
    s.Add("min_num_matches", &O::min_num_matches, "COLMAP Mapper.min_num_matches").Min(1);
    s.Add("timeout_s", &O::timeout_s, "kill colmap after this many seconds (0: never)").Min(0).NoCacheKey();
  }
  bool Check(std::string* why) const {
    if (filter_max_reproj_error.empty()) return *why = "filter_max_reproj_error: give at least one value", false;
    for (double v : filter_max_reproj_error)
      if (!(v > 0)) return *why = "filter_max_reproj_error: values must be > 0", false;
    return true;
  }
};

class SplineBAStage : public Stage<SplineBAStageOptions> {
 public:
  static StageMeta Meta() {
    return {"gt", "spline_ba",
            "The outer loop of the paper (section 3.2): COLMAP triangulation from the current "
            "poses, continuous-time spline bundle adjustment with auto-calibration, "
            "re-triangulation with lower thresholds, until convergence",
            {{"map", "kapture.dataset", "images with initial poses, sensors, rigs (rig poses at scans)"},
             {"features", "kapture.local_features", "keypoints of the images"},
             {"matches", "kapture.matches", "verified matches"}},
            {{"dataset", "kapture.dataset", "refined ground truth: sensors, rigs, trajectories, records, reconstruction"},
             {"trajectories", "kapture.trajectories", "the same folder, as refined poses"},
             {"model", "colmap.model", "model/ + database.db"},
             {"reconstruction", "kapture.reconstruction", "points3d.txt, observations.txt, keypoints"},
             {"report", "report", "table4.md/.csv, rounds.md/.csv, spline_ba.json, alignments.csv"}}};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

// -------------------------------------------------------- eval/calibration
struct CalibrationEvalOptions {
  std::string reference;  // Kapture with the true sensors, rigs and camera poses.
  std::vector<std::string> labels;  // One per estimate; empty: node names.
  std::vector<std::string> groups = {"industrial=ind_.*", "smartphone=phone_.*"};
  std::string alignment = "se3";
  std::string title = "Camera poses and calibration against the reference";
  static void Declare(ParamSchema<CalibrationEvalOptions>& s) {
    using O = CalibrationEvalOptions;
    s.Add("reference", &O::reference, "kapture with the true sensors.txt, rigs.txt and camera poses (the simulator's output)").Path().Required();
    s.Add("labels", &O::labels, "row label of each estimate (default: node names)");
    s.Add("groups", &O::groups, "camera groups NAME=REGEX on sensor ids");
    s.Add("alignment", &O::alignment, "alignment of the estimated poses: none or one SE(3) per estimate").Choices({"none", "se3"});
    s.Add("title", &O::title, "heading of calibration.md");
  }
};

class CalibrationEvalStage : public Stage<CalibrationEvalOptions> {
 public:
  static StageMeta Meta() {
    return {"eval", "calibration",
            "Camera pose RMS errors, focal errors and camera rotation errors of one or more "
            "estimates against a reference, per camera group (one table row per estimate)",
            {{"estimates", "kapture.trajectories", "refined sensors, rigs, trajectories", LF_PORT_MULTIPLE}},
            {{"report", "report", "calibration.md, calibration.csv, per_camera.csv"}}};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

}  // namespace locforge::sfm_gt

#endif  // LOCFORGE_PLUGINS_SFM_GT_STAGES_H_

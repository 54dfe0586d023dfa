// gt/spline_ba: the outer loop of the paper's SfM refinement (section 3.2),
// spline_ba/outer_loop.h, over the spline bundle adjuster of spline_ba/ba/.
// Its parameters are the loop's options and, in place, the bundle
// adjuster's (SplineBAOptions: one declaration, one default each).
#include "locforge/units.h"
#include "locforge/plugin.h"
#include "outer_loop.h"

// The outer loop's options are declared beside the stage that binds them.
namespace locforge::sfm_gt {

void OuterLoopOptions::Declare(ParamSchema<OuterLoopOptions>& s) {
  using O = OuterLoopOptions;
  s.Add("rounds", &O::rounds, "most rounds of triangulation + bundle adjustment").Range(1, 50);
  s.Add("filter_max_reproj_error", &O::filter_max_reproj_error,
        "COLMAP filter_max_reproj_error per round (px), lowered round by round; the last repeats");
  s.Add("knot_spacing_s", &O::ba, &sfm::SplineBAOptions::knot_spacing_s, "cubic B-spline knot spacing (s)").Range(1e-3, 100);
  s.Add("use_spline_prior", &O::ba, &sfm::SplineBAOptions::use_spline_prior, "spline pose residuals at each image's timestamp (false: plain BA)");
  s.Add("calibrate_intrinsics", &O::ba, &sfm::SplineBAOptions::calibrate_intrinsics, "optimise the intrinsics of every camera");
  s.Add("calibrate_rotations", &O::ba, &sfm::SplineBAOptions::calibrate_rotations, "optimise the rotation of every camera extrinsic");
  s.AddDegrees("prior_sigma_rotation_deg", &O::ba, &sfm::SplineBAOptions::prior_sigma_rotation_rad, "spline pose residual sigma, rotation (deg)").Min(1e-6);
  s.Add("prior_sigma_translation_m", &O::ba, &sfm::SplineBAOptions::prior_sigma_translation_m, "spline pose residual sigma, translation (m)").Min(1e-9);
  s.AddDegrees("trajectory_prior_sigma_rotation_deg", &O::ba, &sfm::SplineBAOptions::trajectory_prior_sigma_rotation_rad,
        "prior of each spline to its initial (LiDAR) poses, rotation sigma (deg; 0: off)").Min(0);
  s.Add("trajectory_prior_sigma_translation_m", &O::ba, &sfm::SplineBAOptions::trajectory_prior_sigma_translation_m,
        "prior of each spline to its initial (LiDAR) poses, translation sigma (m; 0: off)").Min(0);
  s.Add("scale_trajectories", &O::ba, &sfm::SplineBAOptions::scale_trajectories,
        "scale each sequence's LiDAR poses too, their mean log-scale held at 0 (the images set relative scales)");
  s.Add("nonholonomic_sigma_mps", &O::ba, &sfm::SplineBAOptions::nonholonomic_sigma_mps,
        "wheeled base, rig origin at the wheel axle centre, x forward: std of the spline's sideways velocity "
        "(m/s; 0: off)").Min(0);
  s.Add("align_trajectories", &O::ba, &sfm::SplineBAOptions::align_trajectories,
        "estimate a rigid correction of each sequence's LiDAR poses but the first (the images place the sequences)");
  s.AddDegrees("alignment_sigma_rotation_deg", &O::ba, &sfm::SplineBAOptions::alignment_sigma_rotation_rad,
        "align_trajectories: prior of each correction to the LiDAR merge, rotation sigma (deg)").Min(1e-6);
  s.Add("alignment_sigma_translation_m", &O::ba, &sfm::SplineBAOptions::alignment_sigma_translation_m,
        "align_trajectories: prior of each correction to the LiDAR merge, translation sigma (m)").Min(1e-9);
  s.Add("refine_principal_point", &O::ba, &sfm::SplineBAOptions::refine_principal_point, "with calibrate_intrinsics: also the principal points");
  s.Add("fix_aspect_ratio", &O::ba, &sfm::SplineBAOptions::fix_aspect_ratio,
        "with calibrate_intrinsics: keep fy / fx of PINHOLE / OPENCV cameras (planar motion leaves fy nearly unobservable)");
  s.Add("cauchy_scale_px", &O::ba, &sfm::SplineBAOptions::cauchy_scale_px, "Cauchy loss scale of reprojection residuals (px)").Min(1e-3);
  s.Add("estimate_time_offsets", &O::ba, &sfm::SplineBAOptions::estimate_time_offsets,
        "estimate one clock offset per camera (image i tied to the spline at t_i + offset); time_offsets.csv");
  s.Add("max_time_offset_s", &O::ba, &sfm::SplineBAOptions::max_time_offset_s, "bound of each estimated clock offset (s; < knot_spacing_s)").Min(1e-6);
  s.Add("zero_mean_time_offsets", &O::ba, &sfm::SplineBAOptions::zero_mean_time_offsets,
        "with estimate_time_offsets: hold the mean offset at 0 (a common offset looks like a common camera yaw)");
  s.Add("max_iterations", &O::ba, &sfm::SplineBAOptions::max_iterations, "solver iterations per round").Range(1, 10000);
  s.Add("linear_solver", &O::ba, &sfm::SplineBAOptions::linear_solver,
        "BA linear solver: auto (sparse_schur up to sparse_schur_max_images images), sparse_schur, iterative_schur, "
        "dense_schur (Ceres'), or parallel_schur (our Levenberg-Marquardt, the reduced system assembled without locks and factorised by every thread)")
      .Choices({"auto", "sparse_schur", "iterative_schur", "dense_schur", "parallel_schur"});
  s.Add("sparse_library", &O::ba, &sfm::SplineBAOptions::sparse_library,
        "sparse Cholesky of sparse_schur: suite_sparse (CHOLMOD on the system BLAS) or eigen_sparse (no BLAS)")
      .Choices({"suite_sparse", "eigen_sparse"});
  s.Add("parallel_schur_tile", &O::ba, &sfm::SplineBAOptions::parallel_schur_tile,
        "parallel_schur: factorise the reduced system in tiles of this size on every thread (0: CHOLMOD on one thread)")
      .Range(0, 4096);
  s.Add("parallel_schur_tile_flop_ratio", &O::ba, &sfm::SplineBAOptions::parallel_schur_tile_flop_ratio,
        "parallel_schur: tiles only where they cost at most this many times CHOLMOD's operations (sparser: CHOLMOD)")
      .Range(0, 1e9);
  s.Add("sparse_schur_max_images", &O::ba, &sfm::SplineBAOptions::sparse_schur_max_images, "auto: the most images solved with sparse_schur").Min(0);
  s.Add("iterative_eta", &O::ba, &sfm::SplineBAOptions::iterative_eta, "iterative_schur: relative residual of the conjugate gradients").Range(1e-9, 0.999);
  s.Add("pose_tolerance_m", &O::pose_tolerance_m, "convergence: RMS camera-centre change of a round (m)").Min(0);
  s.Add("rotation_tolerance_deg", &O::rotation_tolerance_deg, "convergence: RMS camera rotation change of a round (deg)").Min(0);
  s.Add("reproj_tolerance_px", &O::reproj_tolerance_px, "convergence: change of the mean reprojection error (px)").Min(0);
  AddSecondsPerUnit(s, &O::seconds_per_unit);
  s.Add("sequence_gap_s", &O::sequence_gap_s, "a gap this long between rig poses starts a new trajectory (s)").Min(0);
  s.Add("rig", &O::rig, "device id of the platform poses in trajectories.txt");
  s.Add("keypoints_type", &O::keypoints_type, "keypoints type; empty = the only one");
  s.Add("min_num_matches", &O::min_num_matches, "COLMAP Mapper.min_num_matches").Min(1);
  s.Add("timeout_s", &O::timeout_s, "kill colmap after this many seconds (0: never)").Min(0).NoCacheKey();
}

}  // namespace locforge::sfm_gt

namespace locforge::gt {

using namespace ::locforge::sfm_gt;  // the library this stage wires

namespace {

class SplineBAStage : public Stage<OuterLoopOptions> {
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
             {"report", "report", "table4.md/.csv, rounds.md/.csv, spline_ba.json, alignments.csv"}},
            0,
            // 1.1.0: the bundle adjuster solves from one buffer, so a re-run gives the
            // same bits (1.0.0's last bits followed the heap layout: 0.2 mm on `large`);
            // 1.1.1: one 6-DoF block per image pose (same poses, faster at 2 threads)
            "1.1.1"};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override { OuterLoop(ctx, options()).Run(); }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(SplineBAStage)

}  // namespace locforge::gt

// slam/pose_graph: the stage's parameters (the SLAM's own, slam_options.h,
// plus what the stage reads: the recording, the motion prior, the
// registration back-end), and the wiring of the SLAM (slam.h) between the
// scans kapture, the back-ends and the outputs (slam_output.h).
#include <chrono>
#include <sstream>

#include "lidar_params.h"
#include "locforge/units.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "locforge/registration.h"
#include "slam.h"
#include "slam_output.h"

namespace locforge::lidar {

struct PoseGraphStageOptions {
  std::string dataset;                       // the recording (or the `recording` input)
  std::string motion_prior = "wheel";        // wheel | constant_velocity
  ComponentSpec registration{"registration/gicp"};
  WheelOverrides wheels;
  SlamOptions slam;
  static void Declare(ParamSchema<PoseGraphStageOptions>& s);
  bool Check(std::string* why) const { return slam.Check(why); }
};

class PoseGraphSlam : public Stage<PoseGraphStageOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta{"slam", "pose_graph",
                   "Pose-graph LiDAR SLAM: registration edges, coarse-to-fine loop closures, Ceres; sequences joined "
                   "only when the whole overlap confirms it",
                   {{"scans", "kapture.dataset",
                     "Undistorted platform-frame scans (lidar/preprocess, or source/pcd_keyframes)"},
                    RecordingPort()},
                   {{"trajectories", "kapture.trajectories",
                     "sensors/trajectories.txt: rig at every scan, cameras at every image (the first sequence's "
                     "part); map.pcd/ply, pose_graph.g2o, trajectories.svg/png, joins.csv, slam.json"}}};
    meta.version = "0.12.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

void PoseGraphStageOptions::Declare(ParamSchema<PoseGraphStageOptions>& s) {
  using O = PoseGraphStageOptions;
  s.Add("dataset", &O::dataset,
        "Kapture recording (wheel records, rigs, camera records); required with motion_prior wheel").Path();
  s.Add("motion_prior", &O::motion_prior,
        "Initial guess of sequential registrations: wheel odometry, or constant velocity (no odometry; "
        "every scan a keyframe)").Choices({"wheel", "constant_velocity"});
  s.Add("max_scan_gap_s", &O::slam, &SlamOptions::max_scan_gap_s,
        "constant_velocity: a larger time gap between scans starts a new segment (s)").Min(1e-6);
  s.Add("max_guess_deviation_m", &O::slam, &SlamOptions::max_guess_deviation_m,
        "A sequential registration farther than this from its guess failed (m)").Min(0);
  s.Add("registration", &O::registration,
        "Registration back-end of every registration: a stage id, or {stage: ID, params: {...}}")
      .Implements(LF_REGISTRATION_INTERFACE);
  s.Add("coarse_params", &O::slam, &SlamOptions::coarse_params,
        "key=value overrides of registration's parameters for the wide-gate passes (rough checks, first pass "
        "of sequential and loop registrations), which only seed the final pass; keys the back-end does not "
        "declare are skipped (logged); unused when refine_correspondence_distance_m is 0");
  s.Add("refine_correspondence_distance_m", &O::slam, &SlamOptions::refine_correspondence_distance_m,
        "Final pass of accepted sequential and precise loop registrations with the back-end's "
        "max_correspondence_distance set to this (m; 0: none)").Range(0, 100);
  s.Add("keyframe_distance_m", &O::slam, &SlamOptions::keyframe_distance_m, "Travel between keyframes (m)").Range(0, 100);
  s.Add("keyframe_angle_deg", &O::slam, &SlamOptions::keyframe_angle_deg, "Rotation between keyframes (deg)").Range(0, 360);
  s.Add("min_overlap", &O::slam, &SlamOptions::min_overlap, "Inlier fraction needed by a sequential edge").Range(0, 1);
  s.Add("loop_radius_m", &O::slam, &SlamOptions::loop_radius_m, "Distance of loop candidates (m)").Min(0);
  s.Add("loop_min_travel_m", &O::slam, &SlamOptions::loop_min_travel_m, "Travel since a same-sequence loop candidate (m)").Min(0);
  s.Add("loop_rough_voxel_m", &O::slam, &SlamOptions::loop_rough_voxel_m, "Voxel of the rough loop check (m)").Range(0.01, 10);
  s.Add("loop_rough_overlap", &O::slam, &SlamOptions::loop_rough_overlap, "Inlier fraction of the rough check").Range(0, 1);
  s.Add("loop_rough_error", &O::slam, &SlamOptions::loop_rough_error, "Largest mean residual of the rough check (back-end units; GICP: Mahalanobis)").Min(0);
  s.Add("loop_overlap", &O::slam, &SlamOptions::loop_overlap, "Inlier fraction of the precise loop check").Range(0, 1);
  s.Add("loop_yaw_hypotheses", &O::slam, &SlamOptions::loop_yaw_hypotheses,
        "Headings tried by the rough check between sequences not yet joined").Range(1, 72);
  s.Add("join_seeds", &O::slam, &SlamOptions::join_seeds,
        "Joining parts: seed keyframes nearest a sequence's start (all headings tried)").Range(0, 1000);
  s.Add("join_seed_radius_m", &O::slam, &SlamOptions::join_seed_radius_m, "Seed keyframes lie within this distance of the sequence's start (m)")
      .Min(0);
  s.Add("join_rough_error", &O::slam, &SlamOptions::join_rough_error,
        "Largest mean residual of the rough check of join loops (looser: the overlap evidence judges them)").Min(0);
  s.Add("join_place_candidates", &O::slam, &SlamOptions::join_place_candidates,
        "Place recognition: keyframes of the other part ranked by Scan Context ring key, per keyframe").Range(0, 1000);
  s.Add("join_place_matches", &O::slam, &SlamOptions::join_place_matches,
        "... of which the best by Scan Context distance are checked by registration").Range(0, 100);
  s.Add("join_place_max_distance", &O::slam, &SlamOptions::join_place_max_distance,
        "Largest Scan Context distance of a checked place (0 same, 1 unrelated)").Range(0, 1);
  s.Add("join_verify", &O::slam, &SlamOptions::join_verify, "Loops predicted along the part by the winning frame, tested").Range(0, 1000);
  s.Add("join_min_support", &O::slam, &SlamOptions::join_min_support,
        "Distinct keyframes of the part whose loops must agree with the winning frame").Range(1, 1000);
  s.Add("join_min_verified", &O::slam, &SlamOptions::join_min_verified,
        "... of them found where the frame predicted them").Range(0, 1000);
  s.Add("join_max_translation_m", &O::slam, &SlamOptions::join_max_translation_m,
        "Two loops suggest the same frame when it places their keyframes within this distance (m)").Min(1e-6);
  s.Add("join_max_rotation_deg", &O::slam, &SlamOptions::join_max_rotation_deg, "... and rotations within this angle (deg)").Range(1e-6, 180);
  s.Add("join_max_conflict", &O::slam, &SlamOptions::join_max_conflict,
        "A frame explains the overlap when at most this fraction of the structure both maps saw lies in the "
        "other's free space").Range(0, 1);
  s.Add("join_min_overlap_m", &O::slam, &SlamOptions::join_min_overlap_m,
        "... over at least this much structure seen by both (m of 0.1 m cells)").Range(0.1, 1e6);
  s.Add("join_alias_conflict", &O::slam, &SlamOptions::join_alias_conflict,
        "Repeated structure: a copy of a frame that explains the overlap, turned alike but shifted, with at most "
        "this conflict ...").Range(0, 1);
  s.Add("join_alias_min_shift_m", &O::slam, &SlamOptions::join_alias_min_shift_m,
        "... shifted by at least this much (m), shows the overlap does not fix the translation").Min(1e-3);
  s.Add("join_max_start_offset_m", &O::slam, &SlamOptions::join_max_start_offset_m,
        "With repeated structure, only a frame that puts every sequence start of one part within this distance of "
        "a start of the other is joined (sequences starting at a dock or an entrance; m; 0: none is)").Min(0);
  s.Add("join_rival_conflict_ratio", &O::slam, &SlamOptions::join_rival_conflict_ratio,
        "A distinct frame whose conflict is at most this many times the winner's ...").Range(1, 100);
  s.Add("join_rival_conflict_margin", &O::slam, &SlamOptions::join_rival_conflict_margin, "... plus this fraction ...").Range(0, 1);
  s.Add("join_rival_overlap", &O::slam, &SlamOptions::join_rival_overlap,
        "... over at least this fraction of the winner's overlap makes the join ambiguous (refused)").Range(0, 1);
  s.Add("join_trials", &O::slam, &SlamOptions::join_trials,
        "When no frame explains the overlap as the parts stand, at most this many close frames are joined on trial, "
        "optimised and judged again by join_max_conflict; one that holds, and no other, is joined (0: no trials)")
      .Range(0, 100);
  s.Add("join_trial_max_conflict", &O::slam, &SlamOptions::join_trial_max_conflict,
        "... those with at most this conflict as the parts stand (with repeated structure, only frames keeping the "
        "starts within join_max_start_offset_m)").Range(0, 1);
  s.Add("join_free_space_margin_m", &O::slam, &SlamOptions::join_free_space_margin_m,
        "Structure within this distance of the other map's returns agrees with it (m)").Range(0, 10);
  s.Add("unjoined", &O::slam, &SlamOptions::unjoined,
        "A part that cannot be joined: error (stop, with the evidence and how to give initial_poses) or separate "
        "(kept out of the merged frame; joins.csv)").Choices({"error", "separate"});
  s.Add("loop_stride", &O::slam, &SlamOptions::loop_stride, "Search loops from every n-th keyframe").Range(1, 1000);
  s.Add("loss", &O::slam, &SlamOptions::loss, "Robust loss of loop edges").Choices({"cauchy", "huber", "none"});
  s.Add("loss_scale", &O::slam, &SlamOptions::loss_scale, "Robust loss scale (whitened residual units)").Min(1e-6);
  s.Add("edge_information", &O::slam, &SlamOptions::edge_information,
        "Information of registration edges: the back-end's Hessian rescaled to the sigmas (registration) "
        "or diagonal from the sigmas (fixed)").Choices({"registration", "fixed"});
  s.Add("information_max_ratio", &O::slam, &SlamOptions::information_max_ratio,
        "edge_information registration: weakest direction at most this many sigmas").Range(1, 1e6);
  s.Add("sigma_translation_m", &O::slam, &SlamOptions::sigma_translation_m,
        "Std of registration edges (m; their best-constrained direction with edge_information registration)")
      .Min(1e-6);
  s.Add("sigma_rotation_deg", &O::slam, &SlamOptions::sigma_rotation_deg, "Std of registration edges (deg; likewise)").Min(1e-6);
  s.Add("odometry_sigma_m_per_m", &O::slam, &SlamOptions::odometry_sigma_m_per_m,
        "Std of odometry edges per metre driven (m/m); 0: no odometry edges").Min(0);
  s.Add("odometry_sigma_rotation_deg_per_m", &O::slam, &SlamOptions::odometry_sigma_rotation_deg_per_m,
        "Rotation std of odometry edges per metre driven (deg/m)").Min(1e-6);
  s.Add("odometry_yaw_calibration", &O::slam, &SlamOptions::odometry_yaw_calibration,
        "Scale each sequence's odometry turns by the factor its registrations measure (least squares over "
        "the accepted sequential registrations; slam.json odometry_yaw_scale)");
  s.Add("planar", &O::slam, &SlamOptions::planar, "Level-floor prior: heights and tilts held near the first pose's");
  s.Add("planar_sigma_z_m", &O::slam, &SlamOptions::planar_sigma_z_m, "Height std of the planar prior (m)").Min(1e-6);
  s.Add("planar_sigma_tilt_deg", &O::slam, &SlamOptions::planar_sigma_tilt_deg, "Tilt std of the planar prior (deg)").Min(1e-6);
  s.Add("rounds", &O::slam, &SlamOptions::rounds, "Loop search + optimisation rounds").Range(1, 20);
  s.Add("map_voxel_m", &O::slam, &SlamOptions::map_voxel_m, "Voxel of the accumulated map (m)").Range(0.005, 10);
  s.Add("map_residual_k", &O::slam, &SlamOptions::map_residual_k,
        "Neighbours of the map's point-to-plane residual (slam.json map_plane_residual)").Range(3, 100);
  s.Add("map_residual_radius_m", &O::slam, &SlamOptions::map_residual_radius_m, "Neighbour search radius of that residual (m)")
      .Range(0.01, 10);
  s.Add("map_residual_stride", &O::slam, &SlamOptions::map_residual_stride,
        "That residual evaluated at every n-th map point (neighbours from the whole map)").Range(1, 1000);
  s.Add("initial_poses", &O::slam, &SlamOptions::initial_poses,
        "Manual initial-pose corrections, one 'sequence x y yaw_deg' per entry (start pose in the first "
        "sequence's frame; such a sequence is not joined by loop consensus)");
  AddSecondsPerUnit(s, &O::slam, &SlamOptions::seconds_per_unit);
  DeclareWheelOverrides(s, &O::wheels);
}


namespace {

// The wide-gate passes' back-end: the same one with coarse_params (those it
// declares; the others are reported).
ComponentSpec WideSpec(RunContext& ctx, const PoseGraphStageOptions& o, const RegistrationBackend& refine) {
  ComponentSpec wide_spec = o.registration;
  std::string applied, skipped;
  for (const std::string& entry : o.slam.coarse_params) {
    const size_t eq = entry.find('=');
    const std::string key = entry.substr(0, eq), value = entry.substr(eq + 1);  // SlamOptions::Check: key=value
    if (!refine.Declares(key)) {
      skipped += (skipped.empty() ? "" : ", ") + key;
      continue;
    }
    wide_spec = wide_spec.With(key, value);
    applied += (applied.empty() ? "" : ", ") + entry;
  }
  if (!skipped.empty())
    ctx.Info("pose_graph: coarse_params " + skipped + " not declared by " + o.registration.stage +
             ": its wide-gate passes run to its own stop");
  if (!applied.empty()) ctx.Info("pose_graph: wide-gate passes with " + applied);
  return wide_spec;
}

// Independent registrations (sequential ones guessed by the wheels, the
// rough checks of joins) side by side: one single-threaded back-end pair
// per thread (a back-end aligns on one thread at a time). The back-ends,
// which must outlive the slam.
std::vector<RegistrationBackend> AddWorkerRegistrars(RunContext& ctx, const ComponentSpec& wide_spec,
                                                     const ComponentSpec& narrow_spec, int threads, Slam* slam) {
  std::vector<RegistrationBackend> worker_backends;
  if (threads <= 1) return worker_backends;
  std::vector<std::pair<Registrar, Registrar>> workers;
  worker_backends.reserve(2 * static_cast<size_t>(threads));
  for (int w = 0; w < threads; ++w) {
    worker_backends.push_back(RegistrationBackend::Create(ctx, wide_spec));
    worker_backends.push_back(RegistrationBackend::Create(ctx, narrow_spec));
  }
  for (int w = 0; w < threads; ++w) {
    const RegistrationBackend* wide = &worker_backends[2 * w];
    const RegistrationBackend* narrow = &worker_backends[2 * w + 1];
    workers.emplace_back([wide](const Cloud& s, const Cloud& t, const Pose& g) { return wide->Align(s, t, g, 1); },
                         [narrow](const Cloud& s, const Cloud& t, const Pose& g) { return narrow->Align(s, t, g, 1); });
  }
  slam->SetWorkerRegistrars(std::move(workers));
  return worker_backends;
}

// The scans in time order, their keyframes selected: the scans' records.
std::vector<kapture::DataRecord> SelectKeyframes(RunContext& ctx, kapture::Kapture& k, Slam* slam) {
  std::vector<kapture::DataRecord> scans = k.ReadDataRecords(kapture::kSensorLidar);
  std::stable_sort(scans.begin(), scans.end(), [](const auto& a, const auto& b) { return a.timestamp < b.timestamp; });
  std::vector<ScanStamp> stamps;
  for (const auto& r : scans) stamps.push_back({r.timestamp, SequenceOfScan(r.path)});
  const auto keyframes_start = std::chrono::steady_clock::now();
  slam->SelectKeyframes(stamps, [&](size_t i) {
    return ReadScan(k.ExistingRecordDataPath(scans[i].path, "sensors/records_lidar.txt"));
  });
  slam->AddStepTime("keyframes",
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - keyframes_start).count());
  ctx.Info("pose_graph: " + std::to_string(slam->keyframes().size()) + " keyframes of " +
           std::to_string(scans.size()) + " scans");
  return scans;
}

// Sequences left out of the merged frame: an error with unjoined: error (or
// when a join is inconsistent), else reported.
void CheckJoins(RunContext& ctx, const Slam& slam, const SlamOptions& o) {
  bool separate = false, inconsistent = false;
  for (const auto& j : slam.sequence_joins()) {
    separate = separate || j.status == "separate";
    inconsistent = inconsistent || !j.consistent;
  }
  if (inconsistent || (separate && o.unjoined == "error")) throw Error("slam/pose_graph: " + UnjoinedMessage(slam));
  if (separate) ctx.Info("pose_graph: " + UnjoinedMessage(slam));
}

}  // namespace

void PoseGraphSlam::Run(RunContext& ctx) {
  const PoseGraphStageOptions& o = options();
  const auto start = std::chrono::steady_clock::now();
  // The recording: wheel records (motion_prior wheel), sensors, rigs and camera records.
  const bool has_recording = ctx.HasInput("recording") || !o.dataset.empty();
  const fs::path recording =
      has_recording || o.motion_prior == "wheel" ? RecordingOf(ctx, o.dataset, "slam/pose_graph") : fs::path();
  std::unique_ptr<WheelOdometry> odometry;
  if (o.motion_prior == "wheel")
    odometry = std::make_unique<WheelOdometry>(WheelOdometry::FromKapture(recording, o.wheels.Params()));
  // The final pass of refine_correspondence_distance_m (max_correspondence_distance
  // is a key every registration back-end declares), and the wide-gate passes.
  const bool final_pass = o.slam.refine_correspondence_distance_m > 0;
  const ComponentSpec narrow_spec =
      final_pass ? o.registration.With("max_correspondence_distance", FormatDouble(o.slam.refine_correspondence_distance_m))
                 : o.registration;
  RegistrationBackend refine = RegistrationBackend::Create(ctx, narrow_spec);
  const ComponentSpec wide_spec = final_pass ? WideSpec(ctx, o, refine) : o.registration;
  RegistrationBackend backend = RegistrationBackend::Create(ctx, wide_spec);
  const int threads = ctx.threads();
  SlamHooks hooks;
  hooks.info = [&](const std::string& m) { ctx.Info(m); };
  hooks.progress = [&](size_t done, size_t total, const std::string& what) { ctx.Progress(done, total, what); };
  hooks.check_cancelled = [&] { ctx.ThrowIfCancelled(); };
  Slam slam(
      o.slam, odometry.get(),
      [&](const Cloud& s, const Cloud& t, const Pose& g) { return backend.Align(s, t, g, threads); },
      [&](const Cloud& s, const Cloud& t, const Pose& g) { return refine.Align(s, t, g, threads); }, threads, hooks);
  const std::vector<RegistrationBackend> worker_backends =
      AddWorkerRegistrars(ctx, wide_spec, narrow_spec, threads, &slam);
  const fs::path scans_root = ctx.Input("scans");
  kapture::Kapture k(scans_root);
  const std::vector<kapture::DataRecord> scans = SelectKeyframes(ctx, k, &slam);
  slam.Run();
  CheckJoins(ctx, slam, o.slam);
  // Sensors, rigs and camera records: the recording, else the scans' own.
  const kapture::Kapture dataset(recording.empty() ? scans_root : recording);
  ctx.Info("pose_graph: " + WriteSlamOutputs(slam, o.slam, scans, dataset, ctx.output_dir(), start));
}

LOCFORGE_REGISTER_STAGE(PoseGraphSlam)

}  // namespace locforge::lidar

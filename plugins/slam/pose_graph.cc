// slam/pose_graph: the stage's parameters, and the wiring of the SLAM
// (slam.h) between the scans kapture, the registration back-ends and the
// outputs (slam_output.h).
#include <chrono>
#include <sstream>

#include "locforge/kapture/kapture.h"
#include "locforge/registration.h"
#include "slam.h"
#include "slam_output.h"
#include "lidar_stages.h"

namespace locforge::lidar {

void PoseGraphSlamOptions::Declare(ParamSchema<PoseGraphSlamOptions>& s) {
  using O = PoseGraphSlamOptions;
  s.Add("dataset", &O::dataset,
        "Kapture recording (wheel records, rigs, camera records); required with motion_prior wheel").Path();
  s.Add("motion_prior", &O::motion_prior,
        "Initial guess of sequential registrations: wheel odometry, or constant velocity (no odometry; "
        "every scan a keyframe)").Choices({"wheel", "constant_velocity"});
  s.Add("max_scan_gap", &O::max_scan_gap,
        "constant_velocity: a larger time gap between scans starts a new segment (s)").Min(1e-6);
  s.Add("max_guess_deviation", &O::max_guess_deviation,
        "A sequential registration farther than this from its guess failed (m)").Min(0);
  s.Add("registration", &O::registration, "Registration back-end (stage id of a component)");
  s.Add("registration_params", &O::registration_params, "key=value parameters of the back-end");
  s.Add("refine_correspondence_distance", &O::refine_correspondence_distance,
        "Final pass of accepted sequential and precise loop registrations with the back-end's "
        "max_correspondence_distance set to this (m; 0: none)").Range(0, 100);
  s.Add("keyframe_distance", &O::keyframe_distance, "Travel between keyframes (m)").Range(0, 100);
  s.Add("keyframe_angle", &O::keyframe_angle, "Rotation between keyframes (deg)").Range(0, 360);
  s.Add("min_overlap", &O::min_overlap, "Inlier fraction needed by a sequential edge").Range(0, 1);
  s.Add("loop_radius", &O::loop_radius, "Distance of loop candidates (m)").Min(0);
  s.Add("loop_min_travel", &O::loop_min_travel, "Travel since a same-sequence loop candidate (m)").Min(0);
  s.Add("loop_rough_voxel", &O::loop_rough_voxel, "Voxel of the rough loop check (m)").Range(0.01, 10);
  s.Add("loop_rough_overlap", &O::loop_rough_overlap, "Inlier fraction of the rough check").Range(0, 1);
  s.Add("loop_rough_error", &O::loop_rough_error, "Largest mean residual of the rough check (m)").Min(0);
  s.Add("loop_overlap", &O::loop_overlap, "Inlier fraction of the precise loop check").Range(0, 1);
  s.Add("loop_yaw_hypotheses", &O::loop_yaw_hypotheses,
        "Headings tried by the rough check between sequences not yet joined").Range(1, 72);
  s.Add("join_seeds", &O::join_seeds,
        "Joining parts: seed keyframes nearest a sequence's start (all headings tried)").Range(0, 1000);
  s.Add("join_seed_radius", &O::join_seed_radius, "Seed keyframes lie within this distance of the sequence's start (m)")
      .Min(0);
  s.Add("join_rough_error", &O::join_rough_error,
        "Largest mean residual of the rough check of join loops (m; the overlap evidence judges them)").Min(0);
  s.Add("join_place_candidates", &O::join_place_candidates,
        "Place recognition: keyframes of the other part ranked by Scan Context ring key, per keyframe").Range(0, 1000);
  s.Add("join_place_matches", &O::join_place_matches,
        "... of which the best by Scan Context distance are checked by registration").Range(0, 100);
  s.Add("join_place_max_distance", &O::join_place_max_distance,
        "Largest Scan Context distance of a checked place (0 same, 1 unrelated)").Range(0, 1);
  s.Add("join_verify", &O::join_verify, "Loops predicted along the part by the winning frame, tested").Range(0, 1000);
  s.Add("join_min_support", &O::join_min_support,
        "Distinct keyframes of the part whose loops must agree with the winning frame").Range(1, 1000);
  s.Add("join_min_verified", &O::join_min_verified,
        "... of them found where the frame predicted them").Range(0, 1000);
  s.Add("join_max_translation", &O::join_max_translation,
        "Two loops suggest the same frame when it places their keyframes within this distance (m)").Min(1e-6);
  s.Add("join_max_rotation", &O::join_max_rotation, "... and rotations within this angle (deg)").Range(1e-6, 180);
  s.Add("join_max_conflict", &O::join_max_conflict,
        "A frame explains the overlap when at most this fraction of the structure both maps saw lies in the "
        "other's free space").Range(0, 1);
  s.Add("join_min_overlap", &O::join_min_overlap,
        "... over at least this much structure seen by both (m of 0.1 m cells)").Range(0.1, 1e6);
  s.Add("join_rival_conflict_ratio", &O::join_rival_conflict_ratio,
        "A distinct frame whose conflict is at most this many times the winner's ...").Range(1, 100);
  s.Add("join_rival_conflict_margin", &O::join_rival_conflict_margin, "... plus this fraction ...").Range(0, 1);
  s.Add("join_rival_overlap", &O::join_rival_overlap,
        "... over at least this fraction of the winner's overlap makes the join ambiguous (refused)").Range(0, 1);
  s.Add("join_free_space_margin", &O::join_free_space_margin,
        "Structure within this distance of the other map's returns agrees with it (m)").Range(0, 10);
  s.Add("unjoined", &O::unjoined,
        "A part that cannot be joined: error (stop, with the evidence and how to give initial_poses) or separate "
        "(kept out of the merged frame; joins.csv)").Choices({"error", "separate"});
  s.Add("loop_stride", &O::loop_stride, "Search loops from every n-th keyframe").Range(1, 1000);
  s.Add("loss", &O::loss, "Robust loss of loop edges").Choices({"cauchy", "huber", "none"});
  s.Add("loss_scale", &O::loss_scale, "Robust loss scale (whitened residual units)").Min(1e-6);
  s.Add("edge_information", &O::edge_information,
        "Information of registration edges: the back-end's Hessian rescaled to the sigmas (registration) "
        "or diagonal from the sigmas (fixed)").Choices({"registration", "fixed"});
  s.Add("information_max_ratio", &O::information_max_ratio,
        "edge_information registration: weakest direction at most this many sigmas").Range(1, 1e6);
  s.Add("sigma_translation", &O::sigma_translation,
        "Std of registration edges (m; their best-constrained direction with edge_information registration)")
      .Min(1e-6);
  s.Add("sigma_rotation", &O::sigma_rotation, "Std of registration edges (deg; likewise)").Min(1e-6);
  s.Add("odometry_sigma", &O::odometry_sigma,
        "Std of odometry edges per metre driven (m/m); 0: no odometry edges").Min(0);
  s.Add("odometry_sigma_rotation", &O::odometry_sigma_rotation,
        "Rotation std of odometry edges per metre driven (deg/m)").Min(1e-6);
  s.Add("planar", &O::planar, "Level-floor prior: heights and tilts held near the first pose's");
  s.Add("planar_sigma_z", &O::planar_sigma_z, "Height std of the planar prior (m)").Min(1e-6);
  s.Add("planar_sigma_tilt", &O::planar_sigma_tilt, "Tilt std of the planar prior (deg)").Min(1e-6);
  s.Add("rounds", &O::rounds, "Loop search + optimisation rounds").Range(1, 20);
  s.Add("map_voxel", &O::map_voxel, "Voxel of the accumulated map (m)").Range(0.005, 10);
  s.Add("map_residual_k", &O::map_residual_k,
        "Neighbours of the map's point-to-plane residual (slam.json map_plane_residual)").Range(3, 100);
  s.Add("map_residual_radius", &O::map_residual_radius, "Neighbour search radius of that residual (m)")
      .Range(0.01, 10);
  s.Add("initial_poses", &O::initial_poses,
        "Manual initial-pose corrections, one 'sequence x y yaw_deg' per entry (start pose in the first "
        "sequence's frame; such a sequence is not joined by loop consensus)");
  s.Add("seconds_per_unit", &O::seconds_per_unit, "Duration of one timestamp unit (s)").Range(1e-12, 1);
  LOCFORGE_LIDAR_WHEEL_PARAMS(O);
}

bool PoseGraphSlamOptions::Check(std::string* why) const {
  for (const auto& p : initial_poses) {
    std::string seq;
    Pose start;
    if (!ParseInitialPose(p, &seq, &start)) {
      if (why) *why = "initial_poses: '" + p + "' is not 'sequence x y yaw_deg'";
      return false;
    }
  }
  for (const auto& p : registration_params)
    if (p.find('=') == std::string::npos) {
      if (why) *why = "registration_params: '" + p + "' is not key=value";
      return false;
    }
  return true;
}

namespace {

// The back-end with registration_params and, when max_correspondence > 0,
// max_correspondence_distance overridden (the key every registration
// back-end declares, plugins/registration/README.md).
RegistrationBackend MakeBackend(const PoseGraphSlamOptions& o, RunContext& ctx, double max_correspondence) {
  std::vector<std::pair<std::string, std::string>> params;
  for (const auto& kv : o.registration_params) {
    const size_t eq = kv.find('=');
    if (max_correspondence > 0 && kv.substr(0, eq) == "max_correspondence_distance") continue;
    params.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
  }
  if (max_correspondence > 0) {
    std::ostringstream v;
    v.precision(17);
    v << max_correspondence;
    params.emplace_back("max_correspondence_distance", v.str());
  }
  return RegistrationBackend::Create(ctx, o.registration, params);
}

}  // namespace

void PoseGraphSlam::Run(RunContext& ctx) {
  const PoseGraphSlamOptions& o = options();
  const auto start = std::chrono::steady_clock::now();
  // The recording: wheel records (motion_prior wheel), sensors, rigs and camera records.
  const bool has_recording = ctx.HasInput("recording") || !o.dataset.empty();
  const fs::path recording =
      has_recording || o.motion_prior == "wheel" ? RecordingOf(ctx, o.dataset, "slam/pose_graph") : fs::path();
  std::unique_ptr<WheelOdometry> odometry;
  if (o.motion_prior == "wheel")
    odometry = std::make_unique<WheelOdometry>(WheelOdometry::FromKapture(recording, o.Wheels()));
  RegistrationBackend backend = MakeBackend(o, ctx, 0);
  RegistrationBackend refine = MakeBackend(o, ctx, o.refine_correspondence_distance);
  const int threads = ctx.threads();
  SlamHooks hooks;
  hooks.info = [&](const std::string& m) { ctx.Info(m); };
  hooks.progress = [&](size_t done, size_t total, const std::string& what) { ctx.Progress(done, total, what); };
  hooks.check_cancelled = [&] { ctx.ThrowIfCancelled(); };
  Slam slam(
      o, odometry.get(),
      [&](const Cloud& s, const Cloud& t, const Pose& g) { return backend.Align(s, t, g, threads); },
      [&](const Cloud& s, const Cloud& t, const Pose& g) { return refine.Align(s, t, g, threads); }, threads, hooks);

  const fs::path scans_root = ctx.Input("scans");
  kapture::Kapture k(scans_root);
  std::vector<kapture::DataRecord> scans = k.ReadDataRecords(kapture::kSensorLidar);
  std::stable_sort(scans.begin(), scans.end(), [](const auto& a, const auto& b) { return a.timestamp < b.timestamp; });
  std::vector<ScanStamp> stamps;
  for (const auto& r : scans) stamps.push_back({r.timestamp, SequenceOfScan(r.path)});
  const auto keyframes_start = std::chrono::steady_clock::now();
  slam.SelectKeyframes(stamps, [&](size_t i) {
    return ReadScan(k.ExistingRecordDataPath(scans[i].path, "sensors/records_lidar.txt"));
  });
  slam.AddStepTime("keyframes",
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - keyframes_start).count());
  ctx.Info("pose_graph: " + std::to_string(slam.keyframes().size()) + " keyframes of " +
           std::to_string(scans.size()) + " scans");
  slam.Run();

  bool separate = false, inconsistent = false;
  for (const auto& j : slam.sequence_joins()) {
    separate = separate || j.status == "separate";
    inconsistent = inconsistent || !j.consistent;
  }
  if (inconsistent || (separate && o.unjoined == "error")) throw Error("slam/pose_graph: " + UnjoinedMessage(slam));
  if (separate) ctx.Info("pose_graph: " + UnjoinedMessage(slam));
  // Sensors, rigs and camera records: the recording, else the scans' own.
  const kapture::Kapture dataset(recording.empty() ? scans_root : recording);
  ctx.Info("pose_graph: " + WriteSlamOutputs(slam, o, scans, dataset, ctx.output_dir(), start));
}

}  // namespace locforge::lidar

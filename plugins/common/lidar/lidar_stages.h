// The LiDAR stages of the ground-truth pipeline (paper section 3.1). Declared
// here, defined one per file, registered in plugin.cc.
#ifndef LOCFORGE_PLUGINS_LIDAR_STAGES_H_
#define LOCFORGE_PLUGINS_LIDAR_STAGES_H_

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "locforge/plugin.h"
#include "wheel_odometry.h"

namespace locforge::lidar {

// Wheel parameters shared by the stages: 0 keeps the sensors.txt value.
#define LOCFORGE_LIDAR_WHEEL_PARAMS(O)                                                        \
  s.Add("wheel_radius", &O::wheel_radius, "Wheel radius (m); 0: from sensors.txt").Min(0);  \
  s.Add("wheel_axle", &O::wheel_axle, "Axle length (m); 0: from sensors.txt").Min(0);       \
  s.Add("pulses_per_rev", &O::pulses_per_rev, "Encoder pulses per revolution; 0: from sensors.txt").Min(0)

// The recording a stage reads: its `recording` input when wired (e.g. from
// source/simulator in the same graph), else its `dataset` parameter; a clear
// ParamError when neither or both are given.
fs::path RecordingOf(RunContext& ctx, const std::string& dataset_param, const std::string& stage);
#define LOCFORGE_LIDAR_RECORDING_PORT \
  {"recording", "kapture.dataset", "the recording, instead of the dataset parameter", LF_PORT_OPTIONAL}

// ---- odometry/diff_drive ------------------------------------------------------

struct DiffDriveOptions {
  std::string dataset;       // kapture with sensors/records_wheel_encoder.txt
  double wheel_radius = 0, wheel_axle = 0, pulses_per_rev = 0;
  double rate_hz = 10;       // Output poses per second.
  static void Declare(ParamSchema<DiffDriveOptions>& s) {
    s.Add("dataset", &DiffDriveOptions::dataset,
          "Kapture recording with wheel encoder records (or wire the recording input)").Path();
    LOCFORGE_LIDAR_WHEEL_PARAMS(DiffDriveOptions);
    s.Add("rate_hz", &DiffDriveOptions::rate_hz, "Output platform poses per second").Range(0.1, 1000);
  }
  WheelParams Wheels() const { return {wheel_radius, wheel_axle, pulses_per_rev}; }
};

class DiffDrive : public Stage<DiffDriveOptions> {
 public:
  static StageMeta Meta() {
    return {"odometry", "diff_drive",
            "Differential-drive wheel odometry from encoder ticks (platform trajectory, device rig)",
            {LOCFORGE_LIDAR_RECORDING_PORT},
            {{"trajectories", "kapture.trajectories", "T_rig_odom per segment, at rate_hz"}}};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

// ---- lidar/preprocess ----------------------------------------------------------

struct PreprocessOptions {
  std::string dataset;
  std::string reference_lidar;  // "" : the first lidar of sensors.txt
  double voxel = 0.1;           // m; 0 disables downsampling
  double min_range = 0.5, max_range = 60;
  // Self-hit box in the platform frame: xmin ymin zmin xmax ymax zmax.
  std::vector<double> self_box = {-0.6, -0.45, -0.2, 0.6, 0.45, 2.3};
  double max_pair_dt = 0.06;    // s between the merged scans of two LiDARs
  bool undistort = true;
  double seconds_per_unit = 1e-6;
  double wheel_radius = 0, wheel_axle = 0, pulses_per_rev = 0;
  static void Declare(ParamSchema<PreprocessOptions>& s) {
    s.Add("dataset", &PreprocessOptions::dataset,
          "Kapture recording (LiDAR + wheel records), or wire the recording input").Path();
    s.Add("reference_lidar", &PreprocessOptions::reference_lidar,
          "LiDAR whose scan times are the reference; empty: the first lidar of sensors.txt");
    s.Add("voxel", &PreprocessOptions::voxel, "Voxel size of the downsampling (m); 0: none").Range(0, 10);
    s.Add("min_range", &PreprocessOptions::min_range, "Closer returns are dropped (m)").Min(0);
    s.Add("max_range", &PreprocessOptions::max_range, "Farther returns are dropped (m)").Min(0);
    s.Add("self_box", &PreprocessOptions::self_box,
          "Platform box (xmin ymin zmin xmax ymax zmax, platform frame): returns inside are self hits");
    s.Add("max_pair_dt", &PreprocessOptions::max_pair_dt,
          "Largest time between the scans of two LiDARs merged into one (s)").Range(0, 10);
    s.Add("undistort", &PreprocessOptions::undistort, "Motion-compensate every point (paper eq. 1)");
    s.Add("seconds_per_unit", &PreprocessOptions::seconds_per_unit,
          "Duration of one timestamp unit (1e-6: microseconds)").Range(1e-12, 1);
    LOCFORGE_LIDAR_WHEEL_PARAMS(PreprocessOptions);
  }
  bool Check(std::string* why) const;
  WheelParams Wheels() const { return {wheel_radius, wheel_axle, pulses_per_rev}; }
};

class Preprocess : public PerItemStage<PreprocessOptions> {
 public:
  static StageMeta Meta() {
    return {"lidar", "preprocess",
            "LiDAR scans into the platform frame, undistorted by odometry, merged, filtered, downsampled",
            {LOCFORGE_LIDAR_RECORDING_PORT},
            {{"scans", "kapture.dataset",
              "records_lidar.txt of device 'scan' (platform frame) + one PCD per reference scan"}}};
  }
  using PerItemStage::PerItemStage;
  std::vector<std::string> ListItems(RunContext& ctx) override;
  void ProcessItem(RunContext& ctx, const std::string& item) override;
  void Finalize(RunContext& ctx) override;

  struct Source {
    std::string path;     // under records_data
    std::string lidar;
    Timestamp timestamp;
  };

 private:
  void Load(RunContext& ctx);
  std::mutex mutex_;
  fs::path dataset_;
  bool loaded_ = false;
  std::unique_ptr<WheelOdometry> odometry_;
  std::map<std::string, Pose> T_platform_lidar_;
  std::map<std::string, std::vector<Source>> items_;  // reference path -> scans merged
};

// ---- slam/pose_graph -------------------------------------------------------------

struct PoseGraphSlamOptions {
  std::string dataset;
  // Initial guess of sequential registrations: "wheel" odometry of `dataset`,
  // or "constant_velocity" (the previous keyframe-to-keyframe motion,
  // rescaled to the time step) for recordings without odometry; then every
  // scan is a keyframe and `dataset` is optional (cameras only).
  std::string motion_prior = "wheel";
  double max_scan_gap = 2.0;        // s; constant_velocity: a larger gap starts a new segment
  double max_guess_deviation = 0.3; // m between a sequential registration and its guess
  std::string registration = "registration/gicp";  // back-end stage id
  std::vector<std::string> registration_params;    // "key=value" given to the back-end
  // Final pass of every accepted sequential and precise loop registration,
  // from its result, with the back-end's max_correspondence_distance set to
  // this (m; 0: no final pass). The first pass starts up to a few decimetres
  // off and needs a wide gate; once it has converged, the points a wide gate
  // still pairs are the ones without a true counterpart (people walking
  // through the scans, surfaces seen from one side only), and they pull each
  // registration toward zero motion (the map of the simulator's `small`
  // preset: 0.096 % too small, 0.075 % with this pass; plugins/lidar/README.md).
  double refine_correspondence_distance = 0.3;
  // Registration edges' information: "registration" (the back-end's 6x6
  // Hessian moved into the edge's coordinates and rescaled so its strongest
  // directions have sigma_translation / sigma_rotation, weaker ones down to
  // information_max_ratio x those stds), or "fixed" (diagonal from the sigmas).
  std::string edge_information = "registration";
  double information_max_ratio = 10;
  double keyframe_distance = 0.5;   // m travelled (odometry) between keyframes
  double keyframe_angle = 10;       // deg turned between keyframes
  double min_overlap = 0.5;         // inlier fraction accepted for sequential edges
  double loop_radius = 4;           // m between estimated positions of loop candidates
  double loop_min_travel = 8;       // m travelled since a same-sequence candidate
  double loop_rough_voxel = 0.5;    // m, clouds of the rough check
  double loop_rough_overlap = 0.5;  // inlier fraction of the rough check
  double loop_rough_error = 0.3;    // largest mean residual of the rough check (m)
  double loop_overlap = 0.6;        // inlier fraction of the precise check
  int loop_stride = 2;              // test loops from every n-th keyframe
  int loop_yaw_hypotheses = 12;     // headings tried when joining two sequences
  // Joining parts of the map (sequences, or groups already joined; join.h):
  // loops between them come from seeds (keyframes near a sequence's start,
  // every heading: sequences often start at one spot) and from place
  // recognition (Scan Context) over the whole trajectories; each distinct
  // frame they suggest is judged by the whole overlap of the two maps (the
  // structure of one in the other's free space); a join is made when one
  // frame explains the overlap and no other comes close, else refused.
  int join_seeds = 8;               // seed keyframes (every loop_stride-th from the start)
  double join_seed_radius = 8;      // m from the sequence's start, seed keyframes
  // Largest mean residual of the join loops' rough check (m): looser than
  // loop_rough_error, as the overlap evidence judges the hypotheses.
  double join_rough_error = 1.0;
  int join_place_candidates = 10;   // keyframes of A ranked by ring key per keyframe of B
  int join_place_matches = 2;       // ... of which the best by Scan Context distance are checked
  double join_place_max_distance = 0.35;  // largest Scan Context distance of a checked place
  int join_verify = 12;             // loops predicted by the winning frame along B, tested
  int join_min_support = 3;         // distinct keyframes of B whose loops agree with the winning frame
  int join_min_verified = 2;        // ... found where the frame predicted them
  double join_max_translation = 1.0;   // m, two loops suggest one frame: their keyframes within this ...
  double join_max_rotation = 5;        // deg, ... and their rotations within this
  double join_max_conflict = 0.05;     // fraction of shared tall structure in the other map's free space
  double join_min_overlap = 20;        // m of structure seen by both maps (cells x cell size)
  double join_rival_conflict_ratio = 1.5;   // a distinct frame with a conflict below ratio x the winner's ...
  double join_rival_conflict_margin = 0.02; // ... + margin ...
  double join_rival_overlap = 0.5;          // ... and this fraction of its overlap makes the join ambiguous
  double join_free_space_margin = 0.3;      // m: structure this close to the other map's returns agrees
  // A part that cannot be joined: "error" stops the run with the evidence and
  // how to give initial_poses; "separate" keeps it out of the merged frame
  // (trajectories.txt holds the first sequence's part, joins.csv says why).
  std::string unjoined = "error";
  std::string loss = "cauchy";      // robust loss of loop edges
  double loss_scale = 1.0;          // in whitened residual units
  double sigma_translation = 0.01;  // m, registration edges
  double sigma_rotation = 0.1;      // deg, registration edges
  // m per m driven, odometry edges (0: none). Weak: a wheel radius ~1 % off
  // otherwise leaks its scale into the map (plugins/lidar/README.md).
  double odometry_sigma = 0.1;
  double odometry_sigma_rotation = 2;  // deg per m driven
  bool planar = true;               // level-floor prior (wheeled platform)
  double planar_sigma_z = 0.01;     // m
  double planar_sigma_tilt = 0.1;   // deg
  int rounds = 3;                   // loop search + optimisation rounds
  double map_voxel = 0.05;          // m, accumulated map
  int map_residual_k = 10;          // neighbours of the map's point-to-plane residual
  double map_residual_radius = 0.5; // m, their search radius
  // Manual initial-pose corrections: per sequence "seq x y yaw_deg" entries.
  std::vector<std::string> initial_poses;
  double seconds_per_unit = 1e-6;
  double wheel_radius = 0, wheel_axle = 0, pulses_per_rev = 0;
  static void Declare(ParamSchema<PoseGraphSlamOptions>& s);
  bool Check(std::string* why) const;
  WheelParams Wheels() const { return {wheel_radius, wheel_axle, pulses_per_rev}; }
};

// One initial_poses entry, "sequence x y yaw_deg": false when malformed.
bool ParseInitialPose(const std::string& entry, std::string* sequence, Pose* start);

class PoseGraphSlam : public Stage<PoseGraphSlamOptions> {
 public:
  static StageMeta Meta() {
    return {"slam", "pose_graph",
            "Pose-graph LiDAR SLAM: registration edges, coarse-to-fine loop closures, Ceres, sequences merged",
            {{"scans", "kapture.dataset",
              "Undistorted platform-frame scans (lidar/preprocess, or source/pcd_keyframes)"},
             LOCFORGE_LIDAR_RECORDING_PORT},
            {{"trajectories", "kapture.trajectories",
              "sensors/trajectories.txt: rig at every scan, cameras at every image; map.pcd/ply, "
              "pose_graph.g2o, trajectories.svg/png, slam.json"}}};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

// ---- source/pcd_keyframes -------------------------------------------------------

// Imports a folder of PCD/PLY keyframes (already motion-compensated, e.g.
// ../shared/data/lidar/balm_indoor/scans) as the `scans` kapture that
// slam/pose_graph reads, with timestamps (and reference poses) from a TUM
// file whose i-th pose belongs to the i-th scan in file-name order.
struct PcdKeyframesOptions {
  std::string scans;         // folder of .pcd / .ply files
  std::string poses;         // TUM file (timestamp tx ty tz qx qy qz qw, T_world_lidar); "" : none
  double period = 0.1;       // s between scans when there is no TUM file
  std::string sequence = "seq";
  double voxel = 0;          // m; 0 keeps the points as they are
  double min_range = 0, max_range = 1e9;
  static void Declare(ParamSchema<PcdKeyframesOptions>& s) {
    using O = PcdKeyframesOptions;
    s.Add("scans", &O::scans, "Folder of keyframe clouds (.pcd/.ply, sensor frame, file-name order)")
        .Path().Required();
    s.Add("poses", &O::poses,
          "TUM file: timestamps and reference poses (world <- lidar), i-th line for the i-th scan").Path();
    s.Add("period", &O::period, "Seconds between scans when no TUM file is given").Range(1e-6, 1e6);
    s.Add("sequence", &O::sequence, "Sequence name (folder of the records)");
    s.Add("voxel", &O::voxel, "Voxel downsampling (m); 0: none").Range(0, 10);
    s.Add("min_range", &O::min_range, "Closer returns are dropped (m)").Min(0);
    s.Add("max_range", &O::max_range, "Farther returns are dropped (m)").Min(0);
  }
  bool Check(std::string* why) const;
};

class PcdKeyframes : public Stage<PcdKeyframesOptions> {
 public:
  static StageMeta Meta() {
    return {"source", "pcd_keyframes",
            "Folder of LiDAR keyframes (+ TUM timestamps / reference poses) as a scans kapture",
            {},
            {{"scans", "kapture.dataset",
              "records_lidar.txt of device 'scan' + one PCD per keyframe; trajectories.txt: the "
              "reference poses (device rig) when a TUM file is given"}}};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

// ---- calib/lidar_to_lidar ---------------------------------------------------------

struct LidarToLidarOptions {
  std::string dataset;
  std::string reference_lidar;   // "" : the first lidar of sensors.txt
  std::string lidar;             // calibrated one; "" : the other lidar
  int scans = 10;                // scans accumulated
  int iterations = 2;            // undistortion / registration alternations
  double voxel = 0.1, min_range = 0.5, max_range = 60;
  std::string registration = "registration/gicp";
  std::vector<std::string> registration_params;
  // Start offset applied to rigs.txt (x y z m, roll pitch yaw deg): tests, bad CAD.
  std::vector<double> initial_offset = {0, 0, 0, 0, 0, 0};
  double seconds_per_unit = 1e-6;
  double wheel_radius = 0, wheel_axle = 0, pulses_per_rev = 0;
  static void Declare(ParamSchema<LidarToLidarOptions>& s) {
    using O = LidarToLidarOptions;
    s.Add("dataset", &O::dataset, "Kapture recording with two lidars (or wire the recording input)").Path();
    s.Add("reference_lidar", &O::reference_lidar, "Reference lidar; empty: the first of sensors.txt");
    s.Add("lidar", &O::lidar, "Calibrated lidar; empty: the other one");
    s.Add("scans", &O::scans, "Scans accumulated").Range(1, 1000);
    s.Add("iterations", &O::iterations, "Undistortion / registration alternations").Range(1, 10);
    s.Add("voxel", &O::voxel, "Voxel of the accumulated clouds (m)").Range(0.01, 10);
    s.Add("min_range", &O::min_range, "Closer returns dropped (m)").Min(0);
    s.Add("max_range", &O::max_range, "Farther returns dropped (m)").Min(0);
    s.Add("registration", &O::registration, "Registration back-end (stage id)");
    s.Add("registration_params", &O::registration_params, "key=value parameters of the back-end");
    s.Add("initial_offset", &O::initial_offset, "Offset applied to the rigs.txt extrinsic first (x y z m, roll pitch yaw deg)");
    s.Add("seconds_per_unit", &O::seconds_per_unit, "Duration of one timestamp unit (s)").Range(1e-12, 1);
    LOCFORGE_LIDAR_WHEEL_PARAMS(O);
  }
  bool Check(std::string* why) const;
  WheelParams Wheels() const { return {wheel_radius, wheel_axle, pulses_per_rev}; }
};

class LidarToLidar : public Stage<LidarToLidarOptions> {
 public:
  static StageMeta Meta() {
    return {"calib", "lidar_to_lidar", "Extrinsic of a second LiDAR w.r.t. the first by registration on their shared view",
            {LOCFORGE_LIDAR_RECORDING_PORT},
            {{"rig", "kapture.dataset", "sensors/rigs.txt with the calibrated extrinsic, calib.json"}}};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_LIDAR_STAGES_H_

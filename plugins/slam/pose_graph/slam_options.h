// Options of the SLAM (slam.h): one declaration, bound by the stage
// slam/pose_graph to its YAML keys (the same names).
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_OPTIONS_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_OPTIONS_H_

#include <string>
#include <vector>

#include "locforge/units.h"
#include "locforge/pose.h"

namespace locforge::lidar {

struct SlamOptions {
  // constant velocity (no odometry): a larger time gap between scans starts a new segment
  double max_scan_gap_s = 2.0;
  // a sequential registration farther than this from its guess failed
  double max_guess_deviation_m = 0.3;
  // Final pass of every accepted sequential and precise loop registration,
  // from its result, with the back-end's max_correspondence_distance set to
  // this (0: none). The first pass starts up to decimetres off and needs a
  // wide gate; once converged, the points a wide gate still pairs are those
  // without a true counterpart (people walking through the scans, surfaces
  // seen from one side), and they pull a registration toward zero motion.
  double refine_correspondence_distance_m = 0.3;
  // The wide-gate passes (rough checks, the first pass of sequential and
  // loop registrations) only seed that final pass, which converges fully:
  // registration's own stop (GICP: 1e-4 rad) there is wasted work. These
  // key=value overrides of registration's parameters apply to them (keys the
  // back-end does not declare are skipped): 20x / 10x looser for GICP, half
  // the iterations of the LiDAR half (docs/results/slam.md, throughput).
  std::vector<std::string> coarse_params = {"rotation_epsilon=0.002", "translation_epsilon=0.001"};
  // Registration edges' information: "registration" (the back-end's 6x6
  // Hessian moved into the edge's coordinates and rescaled so its strongest
  // directions have the sigmas, weaker ones down to information_max_ratio x
  // those stds), or "fixed" (diagonal from the sigmas).
  std::string edge_information = "registration";
  double information_max_ratio = 10;
  double keyframe_distance_m = 0.5;   // travelled between keyframes (odometry)
  double keyframe_angle_deg = 10;     // turned between keyframes
  double min_overlap = 0.5;           // inlier fraction accepted for sequential edges
  double loop_radius_m = 4;           // between estimated positions of loop candidates
  double loop_min_travel_m = 8;       // travelled since a same-sequence candidate
  double loop_rough_voxel_m = 0.5;    // clouds of the rough check
  double loop_rough_overlap = 0.5;    // inlier fraction of the rough check
  // Largest mean residual of the rough check, in the back-end's units (GICP:
  // Mahalanobis, ~0.3 on the simulator's scans, ~1 on real ones).
  double loop_rough_error = 0.3;
  double loop_overlap = 0.6;          // inlier fraction of the precise check
  int loop_stride = 2;                // loops from every n-th keyframe
  int loop_yaw_hypotheses = 12;       // headings tried from a sequence's start (and by constant velocity)
  // Joining parts of the map (sequences, or groups already joined; join.h):
  // loops between them come from seeds (keyframes near a sequence's start,
  // every heading: sequences often start at one spot) and from place
  // recognition (Scan Context) over the whole trajectories; each distinct
  // frame they suggest is judged by the whole overlap of the two maps (tall
  // structure of one in the other's free space); a join is made when one
  // frame explains the overlap and no other comes close, else refused.
  int join_seeds = 8;                 // seed keyframes (every loop_stride-th from the start)
  double join_seed_radius_m = 8;      // from the sequence's start, seed keyframes
  double join_rough_error = 1.0;      // rough check of join loops (looser: the evidence judges them)
  int join_place_candidates = 10;     // keyframes of A ranked by ring key per keyframe of B
  int join_place_matches = 2;         // ... of which the best by Scan Context distance are checked
  double join_place_max_distance = 0.35;  // largest Scan Context distance of a checked place
  int join_verify = 12;               // loops predicted by the winning frame along B, tested
  int join_min_support = 3;           // distinct keyframes of B whose loops agree with the winning frame
  int join_min_verified = 2;          // ... found where the frame predicted them
  double join_max_translation_m = 1.0;  // two loops suggest one frame: their keyframes within this ...
  double join_max_rotation_deg = 5;     // ... and their rotations within this
  double join_max_conflict = 0.013;     // fraction of shared tall structure in the other map's free space
  double join_min_overlap_m = 20;       // structure seen by both maps (cells x cell size)
  // Repeated structure: a frame that explains the overlap has a copy turned
  // alike (join_max_rotation_deg) but shifted by join_alias_min_shift_m with
  // a conflict of at most join_alias_conflict. Then only a frame that keeps
  // the sequences' starts within join_max_start_offset_m (a dock, an
  // entrance) is joined; 0: none is.
  double join_alias_conflict = 0.05;
  double join_alias_min_shift_m = 3;
  double join_max_start_offset_m = 5;
  double join_rival_conflict_ratio = 1.5;   // a distinct frame with a conflict below ratio x the winner's ...
  double join_rival_conflict_margin = 0.02; // ... + margin ...
  double join_rival_overlap = 0.5;          // ... and this fraction of its overlap makes the join ambiguous
  // No frame explains the overlap as the parts stand: up to join_trials
  // frames within join_trial_max_conflict are joined on trial, optimised and
  // judged again; one that holds and no other is joined (join.h).
  int join_trials = 3;
  double join_trial_max_conflict = 0.08;
  double join_free_space_margin_m = 0.3;    // structure this close to the other map's returns agrees
  // A part that cannot be joined: "error" stops the run with the evidence and
  // how to give initial_poses; "separate" keeps it out of the merged frame
  // (trajectories.txt holds the first sequence's part, joins.csv says why).
  std::string unjoined = "error";
  std::string loss = "cauchy";        // robust loss of loop edges
  double loss_scale = 1.0;            // in whitened residual units
  double sigma_translation_m = 0.01;  // registration edges
  double sigma_rotation_deg = 0.1;    // registration edges
  // Odometry edges per metre driven (0: none). Weak: a wheel radius ~1 %
  // off otherwise leaks its scale into the map along corridors (large seed 1:
  // 0.1 m/m left map_00 0.29 % short, 3.25 cm whole-recording ATE; 0.3: 2.18 cm).
  double odometry_sigma_m_per_m = 0.3;
  double odometry_sigma_rotation_deg_per_m = 2;
  // Calibrate each sequence's odometry turn against its registrations
  // (Slam::CalibrateOdometryYaw): unequal wheel radii turn every spin by the
  // same factor too far or too short, and even weak odometry edges, all
  // biased the same way, pull a full spin 0.2-0.6 deg off where no loop
  // corrects it (large seeds 1 and 4, day-2 sequences).
  bool odometry_yaw_calibration = true;
  bool planar = true;                 // level-floor prior (wheeled platform)
  double planar_sigma_z_m = 0.01;
  double planar_sigma_tilt_deg = 0.1;
  int rounds = 3;                     // join + loop search + optimisation rounds
  double map_voxel_m = 0.05;          // accumulated map
  int map_residual_k = 10;            // neighbours of the map's point-to-plane residual
  double map_residual_radius_m = 0.5; // their search radius
  int map_residual_stride = 4;        // ... evaluated at every n-th map point (a sample: 1/n of the cost)
  // Manual initial-pose corrections: per sequence "seq x_m y_m yaw_deg".
  std::vector<std::string> initial_poses;
  double seconds_per_unit = kDefaultSecondsPerUnit;

  // Combinations the parameter ranges cannot catch (malformed initial_poses).
  bool Check(std::string* why = nullptr) const;
};

// One initial_poses entry, "sequence x_m y_m yaw_deg": false when malformed.
bool ParseInitialPose(const std::string& entry, std::string* sequence, Pose* start);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_OPTIONS_H_

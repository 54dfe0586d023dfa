// Options of the SLAM (slam.h), declared once: SlamOptions::Declare gives
// each its YAML key, default (the in-class initialiser), range and doc, and
// the stage slam/pose_graph binds them in place (ParamSchema::AddGroup).
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_OPTIONS_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_OPTIONS_H_

#include <string>
#include <vector>

#include "locforge/params.h"
#include "locforge/pose.h"
#include "locforge/units.h"

namespace locforge::lidar {

struct SlamOptions {
  double max_scan_gap_s = 2.0;
  double max_guess_deviation_m = 0.3;
  // Once a registration has converged through a wide gate, the points it
  // still pairs are those without a true counterpart (people walking through
  // the scans, surfaces seen from one side): they pull it toward zero motion.
  double refine_correspondence_distance_m = 0.3;
  // The wide-gate passes only seed the final pass, which converges fully:
  // GICP's own 1e-4 rad stop there is wasted work (docs/results/slam.md).
  std::vector<std::string> coarse_params = {"rotation_epsilon=0.002", "translation_epsilon=0.001"};
  std::string edge_information = "registration";
  double information_max_ratio = 10;
  double keyframe_distance_m = 0.5;
  double keyframe_angle_rad = DegreesToRadians(10);
  double min_overlap = 0.5;
  double loop_radius_m = 4;
  double loop_min_travel_m = 8;
  double loop_rough_voxel_m = 0.5;
  double loop_rough_overlap = 0.5;
  double loop_rough_error = 0.3;  // GICP's Mahalanobis: ~0.3 on the simulator's scans, ~1 on real ones
  double loop_overlap = 0.6;
  int loop_stride = 2;
  int loop_yaw_hypotheses = 12;
  // Joins (join.h): loops between parts come from seeds (sequences often
  // start at one spot) and from place recognition; each frame they suggest
  // is judged by the whole overlap of the two maps, and joined only when one
  // frame explains it and no other comes close.
  int join_seeds = 8;
  double join_seed_radius_m = 8;
  double join_rough_error = 1.0;
  int join_place_candidates = 10;
  int join_place_matches = 2;
  double join_place_max_distance = 0.35;
  int join_verify = 12;
  int join_min_support = 3;
  int join_min_verified = 2;
  double join_max_translation_m = 1.0;
  double join_max_rotation_deg = 5;  // degrees: the join consensus compares angles in degrees
  double join_max_conflict = 0.013;
  double join_min_overlap_m = 20;
  double join_alias_conflict = 0.05;
  double join_alias_min_shift_m = 3;
  double join_max_start_offset_m = 5;
  double join_rival_conflict_ratio = 1.5;
  double join_rival_conflict_margin = 0.02;
  double join_rival_overlap = 0.5;
  int join_trials = 3;
  double join_trial_max_conflict = 0.08;
  double join_free_space_margin_m = 0.3;
  // Joining slam/sequences' parts, the keyframe clouds stay in their files
  // and are read when a loop check or a floor grid needs them: a floor's
  // clouds do not fit one node (~2 MB per keyframe).
  int join_clouds_in_memory = 256;
  std::string unjoined = "error";
  std::string loss = "cauchy";
  double loss_scale = 1.0;
  double sigma_translation_m = 0.01;
  double sigma_rotation_rad = DegreesToRadians(0.1);
  // Weak odometry edges: a wheel radius ~1 % off otherwise leaks its scale
  // into the map along corridors where the scans constrain little.
  double odometry_sigma_m_per_m = 0.3;
  double odometry_sigma_rotation_rad_per_m = DegreesToRadians(2);
  // Unequal wheel radii turn every spin by the same factor too far or too
  // short, and even weak odometry edges, all biased alike, pull a full spin
  // off where no loop corrects it (docs/results/slam.md).
  bool odometry_yaw_calibration = true;
  bool planar = true;  // a wheeled platform on a level floor
  double planar_sigma_z_m = 0.01;
  double planar_sigma_tilt_rad = DegreesToRadians(0.1);
  int rounds = 3;
  double map_voxel_m = 0.05;
  int map_residual_k = 10;
  double map_residual_radius_m = 0.5;
  int map_residual_stride = 4;  // a sample: 1/n of the cost
  std::vector<std::string> initial_poses;
  double seconds_per_unit = kDefaultSecondsPerUnit;

  // For ParamSchema<SlamOptions> and, in place, a stage's group.
  template <typename Schema>
  static void Declare(Schema& s) {
    DeclareSequential(s);
    DeclareLoops(s);
    DeclareJoins(s);
    DeclareGraph(s);
    DeclareMap(s);
    AddSecondsPerUnit(s, &SlamOptions::seconds_per_unit);
  }
  // Combinations the parameter ranges cannot catch (malformed initial_poses).
  bool Check(std::string* why = nullptr) const;

 private:
  // Keyframes and the registrations between consecutive ones.
  template <typename Schema>
  static void DeclareSequential(Schema& s) {
    s.Add("max_scan_gap_s", &SlamOptions::max_scan_gap_s,
          "constant_velocity: a larger time gap between scans starts a new segment (s)").Min(1e-6);
    s.Add("max_guess_deviation_m", &SlamOptions::max_guess_deviation_m,
          "A sequential registration farther than this from its guess failed (m)").Min(0);
    s.Add("coarse_params", &SlamOptions::coarse_params,
          "key=value overrides of registration's parameters for the wide-gate passes (rough checks, first pass "
          "of sequential and loop registrations), which only seed the final pass; keys the back-end does not "
          "declare are skipped (logged); unused when refine_correspondence_distance_m is 0");
    s.Add("refine_correspondence_distance_m", &SlamOptions::refine_correspondence_distance_m,
          "Final pass of accepted sequential and precise loop registrations with the back-end's "
          "max_correspondence_distance set to this (m; 0: none)").Range(0, 100);
    s.Add("keyframe_distance_m", &SlamOptions::keyframe_distance_m, "Travel between keyframes (m)").Range(0, 100);
    s.AddDegrees("keyframe_angle_deg", &SlamOptions::keyframe_angle_rad, "Rotation between keyframes (deg)").Range(0, 360);
    s.Add("min_overlap", &SlamOptions::min_overlap, "Inlier fraction needed by a sequential edge").Range(0, 1);
  }
  // Loop candidates and their coarse-to-fine checks.
  template <typename Schema>
  static void DeclareLoops(Schema& s) {
    s.Add("loop_radius_m", &SlamOptions::loop_radius_m, "Distance of loop candidates (m)").Min(0);
    s.Add("loop_min_travel_m", &SlamOptions::loop_min_travel_m, "Travel since a same-sequence loop candidate (m)").Min(0);
    s.Add("loop_stride", &SlamOptions::loop_stride, "Search loops from every n-th keyframe").Range(1, 1000);
    s.Add("loop_rough_voxel_m", &SlamOptions::loop_rough_voxel_m, "Voxel of the rough loop check (m)").Range(0.01, 10);
    s.Add("loop_rough_overlap", &SlamOptions::loop_rough_overlap, "Inlier fraction of the rough check").Range(0, 1);
    s.Add("loop_rough_error", &SlamOptions::loop_rough_error, "Largest mean residual of the rough check (back-end units; GICP: Mahalanobis)").Min(0);
    s.Add("loop_overlap", &SlamOptions::loop_overlap, "Inlier fraction of the precise loop check").Range(0, 1);
    s.Add("loop_yaw_hypotheses", &SlamOptions::loop_yaw_hypotheses,
          "Headings tried by the rough check between sequences not yet joined").Range(1, 72);
  }
  // Joining parts of the map (join.h).
  template <typename Schema>
  static void DeclareJoins(Schema& s) {
    s.Add("join_seeds", &SlamOptions::join_seeds,
          "Joining parts: seed keyframes nearest a sequence's start (all headings tried)").Range(0, 1000);
    s.Add("join_seed_radius_m", &SlamOptions::join_seed_radius_m, "Seed keyframes lie within this distance of the sequence's start (m)")
        .Min(0);
    s.Add("join_rough_error", &SlamOptions::join_rough_error,
          "Largest mean residual of the rough check of join loops (looser: the overlap evidence judges them)").Min(0);
    s.Add("join_place_candidates", &SlamOptions::join_place_candidates,
          "Place recognition: keyframes of the other part ranked by Scan Context ring key, per keyframe").Range(0, 1000);
    s.Add("join_place_matches", &SlamOptions::join_place_matches,
          "... of which the best by Scan Context distance are checked by registration").Range(0, 100);
    s.Add("join_place_max_distance", &SlamOptions::join_place_max_distance,
          "Largest Scan Context distance of a checked place (0 same, 1 unrelated)").Range(0, 1);
    s.Add("join_verify", &SlamOptions::join_verify, "Loops predicted along the part by the winning frame, tested").Range(0, 1000);
    s.Add("join_min_support", &SlamOptions::join_min_support,
          "Distinct keyframes of the part whose loops must agree with the winning frame").Range(1, 1000);
    s.Add("join_min_verified", &SlamOptions::join_min_verified,
          "... of them found where the frame predicted them").Range(0, 1000);
    s.Add("join_max_translation_m", &SlamOptions::join_max_translation_m,
          "Two loops suggest the same frame when it places their keyframes within this distance (m)").Min(1e-6);
    s.Add("join_max_rotation_deg", &SlamOptions::join_max_rotation_deg, "... and rotations within this angle (deg)").Range(1e-6, 180);
    s.Add("join_max_conflict", &SlamOptions::join_max_conflict,
          "A frame explains the overlap when at most this fraction of the structure both maps saw lies in the "
          "other's free space").Range(0, 1);
    s.Add("join_min_overlap_m", &SlamOptions::join_min_overlap_m,
          "... over at least this much structure seen by both (m of 0.1 m cells)").Range(0.1, 1e6);
    s.Add("join_alias_conflict", &SlamOptions::join_alias_conflict,
          "Repeated structure: a copy of a frame that explains the overlap, turned alike but shifted, with at most "
          "this conflict ...").Range(0, 1);
    s.Add("join_alias_min_shift_m", &SlamOptions::join_alias_min_shift_m,
          "... shifted by at least this much (m), shows the overlap does not fix the translation").Min(1e-3);
    s.Add("join_max_start_offset_m", &SlamOptions::join_max_start_offset_m,
          "With repeated structure, only a frame that puts every sequence start of one part within this distance of "
          "a start of the other is joined (sequences starting at a dock or an entrance; m; 0: none is)").Min(0);
    s.Add("join_rival_conflict_ratio", &SlamOptions::join_rival_conflict_ratio,
          "A distinct frame whose conflict is at most this many times the winner's ...").Range(1, 100);
    s.Add("join_rival_conflict_margin", &SlamOptions::join_rival_conflict_margin, "... plus this fraction ...").Range(0, 1);
    s.Add("join_rival_overlap", &SlamOptions::join_rival_overlap,
          "... over at least this fraction of the winner's overlap makes the join ambiguous (refused)").Range(0, 1);
    s.Add("join_trials", &SlamOptions::join_trials,
          "When no frame explains the overlap as the parts stand, at most this many close frames are joined on trial, "
          "optimised and judged again by join_max_conflict; one that holds, and no other, is joined (0: no trials)")
        .Range(0, 100);
    s.Add("join_trial_max_conflict", &SlamOptions::join_trial_max_conflict,
          "... those with at most this conflict as the parts stand (with repeated structure, only frames keeping the "
          "starts within join_max_start_offset_m)").Range(0, 1);
    s.Add("join_free_space_margin_m", &SlamOptions::join_free_space_margin_m,
          "Structure within this distance of the other map's returns agrees with it (m)").Range(0, 10);
    s.Add("join_clouds_in_memory", &SlamOptions::join_clouds_in_memory,
          "Over slam/sequences' parts (the parts input): keyframe clouds held in memory at once, the others read "
          "from the part files when needed (the same results; 0: every cloud read into memory at the start)")
        .Range(0, 1000000000);
    s.Add("unjoined", &SlamOptions::unjoined,
          "A part that cannot be joined: error (stop, with the evidence and how to give initial_poses) or separate "
          "(kept out of the merged frame; joins.csv)").Choices({"error", "separate"});
  }
  // The pose graph: edge weights, priors, rounds, manual starts.
  template <typename Schema>
  static void DeclareGraph(Schema& s) {
    s.Add("loss", &SlamOptions::loss, "Robust loss of loop edges").Choices({"cauchy", "huber", "none"});
    s.Add("loss_scale", &SlamOptions::loss_scale, "Robust loss scale (whitened residual units)").Min(1e-6);
    s.Add("edge_information", &SlamOptions::edge_information,
          "Information of registration edges: the back-end's Hessian rescaled to the sigmas (registration) "
          "or diagonal from the sigmas (fixed)").Choices({"registration", "fixed"});
    s.Add("information_max_ratio", &SlamOptions::information_max_ratio,
          "edge_information registration: weakest direction at most this many sigmas").Range(1, 1e6);
    s.Add("sigma_translation_m", &SlamOptions::sigma_translation_m,
          "Std of registration edges (m; their best-constrained direction with edge_information registration)")
        .Min(1e-6);
    s.AddDegrees("sigma_rotation_deg", &SlamOptions::sigma_rotation_rad, "Std of registration edges (deg; likewise)").Min(1e-6);
    s.Add("odometry_sigma_m_per_m", &SlamOptions::odometry_sigma_m_per_m,
          "Std of odometry edges per metre driven (m/m); 0: no odometry edges").Min(0);
    s.AddDegrees("odometry_sigma_rotation_deg_per_m", &SlamOptions::odometry_sigma_rotation_rad_per_m,
          "Rotation std of odometry edges per metre driven (deg/m)").Min(1e-6);
    s.Add("odometry_yaw_calibration", &SlamOptions::odometry_yaw_calibration,
          "Scale each sequence's odometry turns by the factor its registrations measure (least squares over "
          "the accepted sequential registrations; slam.json odometry_yaw_scale)");
    s.Add("planar", &SlamOptions::planar, "Level-floor prior: heights and tilts held near the first pose's");
    s.Add("planar_sigma_z_m", &SlamOptions::planar_sigma_z_m, "Height std of the planar prior (m)").Min(1e-6);
    s.AddDegrees("planar_sigma_tilt_deg", &SlamOptions::planar_sigma_tilt_rad, "Tilt std of the planar prior (deg)").Min(1e-6);
    s.Add("rounds", &SlamOptions::rounds, "Join + loop search + optimisation rounds").Range(1, 20);
    s.Add("initial_poses", &SlamOptions::initial_poses,
          "Manual initial-pose corrections, one 'sequence x y yaw_deg' per entry (start pose in the first "
          "sequence's frame; such a sequence is not joined by loop consensus)");
  }
  // The accumulated map and its crispness measure.
  template <typename Schema>
  static void DeclareMap(Schema& s) {
    s.Add("map_voxel_m", &SlamOptions::map_voxel_m, "Voxel of the accumulated map (m)").Range(0.005, 10);
    s.Add("map_residual_k", &SlamOptions::map_residual_k,
          "Neighbours of the map's point-to-plane residual (slam.json map_plane_residual)").Range(3, 100);
    s.Add("map_residual_radius_m", &SlamOptions::map_residual_radius_m, "Neighbour search radius of that residual (m)")
        .Range(0.01, 10);
    s.Add("map_residual_stride", &SlamOptions::map_residual_stride,
          "That residual evaluated at every n-th map point (neighbours from the whole map)").Range(1, 1000);
  }
};

// One initial_poses entry, "sequence x_m y_m yaw_deg": false when malformed.
bool ParseInitialPose(const std::string& entry, std::string* sequence, Pose* start);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_OPTIONS_H_

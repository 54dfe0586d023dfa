// The spline bundle adjustment of a problem too large for one node, in
// blocks (issue 40): the platform trajectories are dealt into blocks of
// about equal image counts; each block adjusts its images, its trajectories
// and every point its images observe, and holds its own observations only:
// the other blocks' observations of its points enter as one quadratic
// summary per point, from their images' latest estimate (block coordinate
// descent, Gauss-Seidel order). Between passes a coarse correction moves the
// whole state by the one similarity the blocks cannot move (they hold each
// other; only the LiDAR priors, the lever arms and the kinematics see it).
// Passes repeat until one moves no camera by more than the tolerance. Each
// block is an ordinary RunSplineBA: its memory is that of its own images,
// observations and points. The calibration (intrinsics, camera rotations,
// clock offsets), shared by every block, is held (calibrated in whole rounds).
#ifndef LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_BLOCKED_BA_H_
#define LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_BLOCKED_BA_H_

#include <functional>
#include <string>
#include <vector>

#include "spline_ba.h"

namespace locforge::sfm {

struct BlockedBAOptions {
  // Blocks the trajectories are dealt into (at most one per trajectory; 1:
  // one block, the whole problem).
  int blocks = 1;
  // Passes over all blocks (and the calibration) at most.
  int max_passes = 40;
  // A pass that moves every camera centre less than tolerance_m and every
  // camera rotation less than tolerance_deg ends the iteration (a tenth of
  // the 1 mm / 0.01 deg the blocked result must agree with the whole one).
  double tolerance_m = 1e-4;
  double tolerance_deg = 1e-3;
  // Called after each pass with a one-line summary (e.g. the run's log); may be empty.
  std::function<void(const std::string&)> progress;

  // "" or the first invalid field with the reason.
  std::string CheckMessage() const;
};

struct BlockedBAResult {
  bool usable = false;     // every block solve was usable (the problem was written back)
  bool converged = false;  // the last pass moved the cameras less than the tolerance
  bool cancelled = false;  // options.cancelled stopped a block's solve
  int passes = 0;
  double last_change_m = 0, last_change_deg = 0;  // the last pass' largest camera change
  std::vector<int> block_images;                  // images adjusted by each block
  std::vector<int> block_observations;            // observations in each block's problem
  std::vector<int> block_summaries;               // its points' summaries of the neighbours' observations
  std::vector<SE3Spline> splines;                 // per trajectory, from its block's last solve
  std::vector<Pose> trajectory_alignments;        // per trajectory (identity: the reference)
  double seconds = 0;
  std::string message;                            // why not usable, or a summary
};

// Block of each image: trajectories dealt greedily (largest first) into the
// block with the fewest images so far; images without a trajectory go to
// block 0.
std::vector<int> AssignBlocks(const BAProblem& problem, int blocks);

// Adjusts `problem` in place as RunSplineBA does, block by block. Refused
// (message, nothing changed): invalid options or problem, no spline prior
// (plain BA has no trajectories to deal), scale_trajectories (its mean scale
// ties every trajectory together), any calibration adjusted.
BlockedBAResult RunBlockedSplineBA(const SplineBAOptions& options, const BlockedBAOptions& blocked,
                                   BAProblem* problem);

}  // namespace locforge::sfm

#endif  // LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_BLOCKED_BA_H_

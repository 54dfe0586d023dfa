// Joining a sequence (or a group of already joined sequences) to the graph:
// every verified cross-sequence loop between keyframe `a` of the joined part
// A (world frame) and keyframe `b` of the part B (still in its own frame)
// is a hypothesis of the transform taking B's frame into A's,
//   T_A_B = T_A_a * T_ab * T_B_b^-1,
// and B is joined only when several loops at distinct keyframes of B agree on
// it (a consensus, as RANSAC's), among them loops that the hypothesis
// predicted elsewhere along B and that were then found ("verified"): seed
// loops near the common start alone are not enough, since a symmetric start
// (a square room, a corridor crossing) yields many seed loops agreeing on a
// wrong heading. The loops that disagree with the consensus are rejected,
// not left to the robust loss.
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_JOIN_CONSENSUS_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_JOIN_CONSENSUS_H_

#include <string>
#include <vector>

#include "locforge/pose.h"

namespace locforge::lidar {

struct JoinCandidate {
  int a = 0, b = 0;          // keyframe ids (a in A, b in B)
  Pose T_A_B;                // frame hypothesis (header)
  Eigen::Vector3d p_b = Eigen::Vector3d::Zero();  // b's position in B's frame
  double overlap = 0;        // inlier fraction of the precise registration
  bool predicted = false;    // found where a hypothesis predicted a loop (not a seed)
};

struct JoinConsensusOptions {
  // Two hypotheses agree when they place both candidates' b keyframes
  // within this distance of each other (m) ...
  // Loose enough for the drift of chained registrations along a sequence
  // before the first optimisation; wrong joins are tens of degrees off.
  double max_translation = 1.0;
  // ... and their rotations differ by less than this (deg).
  double max_rotation_deg = 5;
  // Distinct b keyframes needed in the winning cluster ...
  int min_support = 3;
  // ... of which from predicted candidates.
  int min_verified = 3;
  // The best cluster that disagrees with the winner may have at most this
  // fraction of its verified support (else the join is ambiguous and not made).
  double max_rival_ratio = 0.5;
  bool Check(std::string* why = nullptr) const;
};

struct JoinConsensus {
  bool found = false;        // support >= min_support and no close rival
  int centre = -1;           // index of the candidate whose hypothesis won (-1: none)
  Pose T_A_B;                // its hypothesis
  int support = 0;           // distinct b keyframes agreeing with it
  int verified = 0;          // the same among predicted candidates
  int rival_verified = 0;    // `verified` of the best disagreeing cluster
  std::vector<int> inliers;  // candidates agreeing with the centre (indices)
  std::vector<int> outliers; // the others
  std::vector<int> supports; // every candidate's support as a centre
  std::vector<int> verifieds;  // and its verified support
};

// Whether two hypotheses agree (JoinConsensusOptions).
bool HypothesesAgree(const JoinCandidate& x, const JoinCandidate& y, const JoinConsensusOptions& options);

// The best-verified cluster of agreeing hypotheses: every candidate is tried
// as the centre; its verified support (distinct b keyframes among the
// predicted candidates agreeing with it) ranks it first, then its support
// (the same among all candidates), then the summed overlap; the rival is the
// best-verified centre that disagrees with the winner.
JoinConsensus FindJoinConsensus(const std::vector<JoinCandidate>& candidates, const JoinConsensusOptions& options);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_JOIN_CONSENSUS_H_

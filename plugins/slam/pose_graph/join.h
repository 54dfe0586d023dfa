// Deciding a join of two parts of the map (sequences, or groups of sequences
// already joined) from the hypotheses of their relative frame T_A_B that the
// loops between them suggest (join_consensus.h), each judged by the evidence
// of the whole overlap (floor_grid.h): a join is made only when one
// hypothesis explains the overlap and no distinct one comes close; otherwise
// it is refused and reported with the rival hypotheses.
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_JOIN_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_JOIN_H_

#include <string>
#include <vector>

#include "floor_grid.h"
#include "join_consensus.h"

namespace locforge::lidar {

// One frame hypothesis: a cluster of agreeing loops.
struct JoinHypothesis {
  Pose T_A_B;
  std::vector<int> loops;    // candidates (indices) agreeing with it
  int support = 0;           // distinct keyframes of B among them
  JoinEvidence evidence;     // of the whole overlap under T_A_B
  // Farthest start of a sequence of B from every start of A, under T_A_B (m).
  double start_offset_m = 0;
  // Trial (TrialCandidates): the overlap once B was joined by this frame
  // with its loops and the graph optimised.
  bool tried = false;
  JoinEvidence after;
};

// Groups candidates into hypotheses: the best-overlapping unassigned
// candidate opens a cluster, every candidate agreeing with it joins it.
std::vector<JoinHypothesis> ClusterHypotheses(const std::vector<JoinCandidate>& candidates,
                                              const JoinConsensusOptions& agreement);

struct JoinDecisionOptions {
  // A hypothesis explains the overlap when at most this fraction of the
  // tall structure seen by both maps lies in the other's free space (a right
  // frame leaves what the maps' drift and moved objects put there; a wrong
  // one in a floor of repeated rooms can leave as little as a few percent) ...
  double max_conflict = 0.013;
  // ... over at least this many agreeing structure cells (each way).
  int64_t min_agreeing = 200;
  // A distinct hypothesis is a rival, and the join is refused as ambiguous,
  // when its conflict fraction is at most rival_conflict_ratio x the
  // winner's + rival_conflict_margin (the winner's own conflicts are people
  // and moved objects: a rival within that noise is as good an answer) and
  // it agrees over at least rival_overlap of the winner's cells.
  // Repeated structure (a floor of identical rooms): a frame that explains
  // the overlap has a copy turned alike (within alias_max_rotation_deg) but
  // shifted by at least alias_min_shift_m whose conflict is at most
  // alias_conflict. The overlap then does not fix the translation, and only
  // a frame that puts every start of B within max_start_offset_m of a start
  // of A is an answer (sequences of one recording starting at a dock or an
  // entrance; 0: no such prior, such joins are refused).
  double alias_conflict = 0.05;
  double alias_min_shift_m = 3;
  double alias_max_rotation_deg = 5;
  double max_start_offset_m = 0;
  double rival_conflict_ratio = 1.5;
  double rival_conflict_margin = 0.02;
  double rival_overlap = 0.5;
  // Trials: when no frame explains the overlap as the parts stand (each
  // part's drift, not yet corrected by the other's loops, puts far structure
  // tenths of a metre off), up to max_trials frames with a conflict of at
  // most trial_max_conflict are joined on trial, optimised, and judged again
  // by max_conflict; with repeated structure among them, only those keeping
  // the starts together are tried. One that holds, and no other, is joined.
  int max_trials = 3;
  double trial_max_conflict = 0.08;
  bool Check(std::string* why = nullptr) const;
};

struct JoinDecision {
  enum class Status { kJoined, kAmbiguous, kNoEvidence };
  Status status = Status::kNoEvidence;
  int winner = -1;  // hypothesis index (also the best one when refused)
  int rival = -1;   // the closest distinct hypothesis, -1 if none
  std::string reason;
};
const char* ToString(JoinDecision::Status status);

// The decision among hypotheses whose evidence is filled in.
JoinDecision DecideJoin(const std::vector<JoinHypothesis>& hypotheses, const JoinDecisionOptions& options);

// The hypotheses to try when DecideJoin found no frame that explains the
// overlap (none when one does: DecideJoin has decided), best first.
std::vector<int> TrialCandidates(const std::vector<JoinHypothesis>& hypotheses, const JoinDecisionOptions& options);

// The decision once the candidates' `after` evidence is filled in (`tried`
// set): joined when exactly one holds, ambiguous when several do, else
// `before` (DecideJoin's refusal) with what the trials read.
JoinDecision DecideAfterTrials(const std::vector<JoinHypothesis>& hypotheses, const JoinDecision& before,
                               const JoinDecisionOptions& options);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_JOIN_H_

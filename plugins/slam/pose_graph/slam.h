// The pose-graph LiDAR SLAM behind slam/pose_graph (paper section 3.1):
// keyframes of undistorted scans, sequential registration edges (plus weak
// odometry edges), loop closures coarse to fine, Ceres on SE(3), and
// sequences joined into one frame only when the whole overlap confirms the
// join (join.h). The stage (pose_graph_stage.cc) reads the scans, creates
// the registration back-ends and writes what this computes.
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_H_

#include <cmath>
#include <functional>
#include <map>
#include <mutex>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "floor_grid.h"
#include "join.h"
#include "keyframes.h"
#include "locforge/kapture/types.h"
#include "loop_search.h"
#include "pose_graph.h"
#include "slam_options.h"
#include "slam_part.h"

namespace locforge::lidar {

// A turn about the vertical (rad), and the heading of a pose (rad): the
// platform moves on a level floor.
inline Pose YawPose(double yaw, const Eigen::Vector3d& t = Eigen::Vector3d::Zero()) {
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())), t);
}
inline double YawOf(const Pose& T) {
  const Eigen::Vector3d x = T.R().col(0);
  return std::atan2(x.y(), x.x());
}

// Headings the join's loops found, to be seeded at B's start too (slam_join.cc):
// those two loops agree on (one loop alone is as often noise), first time
// seen, more than max_rotation_deg from the turns already tried and from each other.
std::vector<double> PlaceHeadings(const std::vector<JoinCandidate>& candidates, const std::vector<double>& turns,
                                  double max_rotation_deg);

// What the algorithm reports and asks of its caller.
struct SlamHooks {
  std::function<void(const std::string&)> info = [](const std::string&) {};
  std::function<void(size_t, size_t, const std::string&)> progress = [](size_t, size_t, const std::string&) {};
  std::function<void()> check_cancelled = [] {};
};

// One attempt to join part B to part A.
struct JoinAttempt {
  int round = 0;
  std::string a, b;                 // the parts' sequences, '+'-joined
  JoinDecision::Status status = JoinDecision::Status::kNoEvidence;
  std::string reason;
  int candidates = 0;               // loops found between them (seeds, places, predicted)
  int hypotheses = 0;               // distinct frames they suggested
  int winner = -1, rival = -1;      // indices into frames (-1: none)
  int predicted_found = 0, predicted_tested = 0;
  Pose T_A_B;                       // the frame applied (joined)
  std::vector<JoinHypothesis> frames;  // every frame considered, with its evidence
  // The evidence the decision used: after the trial for a frame tried, else as the parts stood.
  static const JoinEvidence& Decisive(const JoinHypothesis& h) { return h.tried ? h.after : h.evidence; }
};

// Where every sequence ended up.
struct SequenceJoin {
  std::string sequence;
  std::string status;        // anchor | joined | manual | separate
  std::string component;     // first sequence of its part
  int round = 0;             // round it joined in (0: anchor or manual)
  // After the last optimisation: the sequence's map against the rest of its
  // part (no evidence when alone).
  JoinEvidence final_evidence;
  bool consistent = true;
};

class Slam {
 public:
  // odometry: null for motion_prior constant_velocity. `registrar` runs every
  // registration; `refine` the final pass of refine_correspondence_distance
  // (unused when that is 0).
  Slam(const SlamOptions& options, const WheelOdometry* odometry, Registrar registrar, Registrar refine,
       int threads, SlamHooks hooks);

  // One (wide-gate, final-pass) registrar pair per worker thread, each
  // running single-threaded: with wheel odometry the sequential
  // registrations do not depend on each other, so they run side by side
  // (the same results as one at a time; fewer synchronisations).
  void SetWorkerRegistrars(std::vector<std::pair<Registrar, Registrar>> workers) { workers_ = std::move(workers); }

  // Keyframes of `scans` (time order; read(i) loads scan i in the rig frame).
  // None (no scan, or none the odometry covers) throws InputError unless `none_is_error` is false.
  void SelectKeyframes(const std::vector<ScanStamp>& scans, const std::function<Cloud(size_t)>& read,
                       bool none_is_error = true);
  // Sequential edges, rounds of joins, loops and optimisation, final checks:
  // RunWithinParts then RunJoins.
  void Run();
  // Each part alone: sequential edges, its own loops, optimised.
  void RunWithinParts();
  // Rounds of joins, loops and optimisation, then the final checks.
  void RunJoins();

  // After RunWithinParts on the scans of one sequence: its part (slam_part.h).
  SlamPart ExportPart() const;
  // Instead of SelectKeyframes and RunWithinParts: the parts of every
  // sequence, each computed on its own, merged as the joint run orders its
  // keyframes (time order; ids renumbered). Throws InputError when two parts
  // hold one sequence.
  void AdoptParts(std::vector<SlamPart> parts);

  // T_world_rig at t, in t's part's frame; false when no keyframe is near.
  // `from`: the keyframe it was taken from (its part is t's).
  Pose PoseAt(Timestamp t, bool* found, const Keyframe** from = nullptr) const;
  // The part of `sequence` (its first keyframe's id) and of the first sequence.
  int ComponentOf(const std::string& sequence) const { return component_.at(sequence); }
  int AnchorComponent() const;
  int threads() const { return threads_; }

  const std::vector<Keyframe>& keyframes() const { return keyframes_; }
  const PoseGraph& graph() const { return graph_; }
  const PoseGraph& initial_graph() const { return before_; }
  const std::vector<JoinAttempt>& join_attempts() const { return attempts_; }
  const std::vector<SequenceJoin>& sequence_joins() const { return sequence_joins_; }
  const SlamStats& stats() const { return stats_; }
  // Adds `seconds` to a step of stats().steps (the stage times its own steps too).
  void AddStepTime(const std::string& step, double seconds);
  // Floor grid of a set of keyframes at their current poses.
  FloorGrid MakeFloor(const std::vector<const Keyframe*>& keyframes) const;
  // A keyframe's full cloud: in memory, or read from its part file (at most
  // join_clouds_in_memory of those held at once, least recently used dropped).
  std::shared_ptr<const Cloud> CloudOf(const Keyframe& kf) const;

 private:
  RegistrationResult Refine(const RegistrationResult& first, const Cloud& source, const Cloud& target);
  RegistrationResult Refine(const RegistrationResult& first, const Cloud& source, const Cloud& target,
                            const Registrar& refine);
  LoopCheckOptions LoopOptions(double rough_error) const;
  Refiner MakeRefiner();
  std::vector<RegistrationResult> CheckLoop(const Keyframe& a, const Keyframe& b, const std::vector<Pose>& guesses,
                                            double rough_error);
  Pose MotionGuess(size_t i) const;
  Matrix6d EdgeInformation(const RegistrationResult& r, const Pose& T_ab);
  void AddSequentialEdges();
  // Keyframe i against i-1 from the motion guess (and its alternatives): true
  // when accepted (then `r`, refined); `guess`: the guess it started from.
  bool RegisterSequential(size_t i, Pose* guess, RegistrationResult* r);
  bool RegisterSequential(size_t i, Pose* guess, RegistrationResult* r, const Registrar& registrar,
                          const Registrar& refine);
  struct SequentialResult {
    bool done = false, ok = false;
    Pose guess;
    RegistrationResult r;
  };
  // fn(n, worker) for n in [0, count), side by side on the worker registrars
  // (runs of consecutive n per worker); false (nothing run) without several
  // workers. Hooks are called from this thread only; the first exception of
  // any worker is rethrown once all stopped.
  bool ForEachOnWorkers(size_t count, const std::function<void(size_t n, size_t worker)>& fn,
                        const std::string& what);
  // RegisterSequential of each keyframe of `items` (into out[i]), side by side
  // on the worker registrars when there are several and the guesses come
  // from the wheels; else nothing is done here. `what`: the progress label.
  void RegisterSequentialAll(const std::vector<size_t>& items, std::vector<SequentialResult>* out,
                             const std::string& what);
  // Keyframe i's result from RegisterSequentialAll when it ran there, else RegisterSequential now.
  bool RegisteredSequential(size_t i, const std::vector<SequentialResult>& side_by_side, Pose* guess,
                            RegistrationResult* r);
  // CalibrateOdometryYaw, then RedeskewKeyframes, the accepted sequential
  // registrations of the keyframes it changed redone (sequential_edge: per
  // keyframe i, the edge (i-1, i) or -1), and the initial estimate chained again.
  void CalibrateAndRedo(const std::map<std::string, std::vector<std::pair<size_t, double>>>& odometry_edges,
                        const std::vector<long>& sequential_edge, const std::vector<bool>& accepted);
  // Keyframes of calibrated sequences (odometry_yaw_scale != 1) undistorted
  // again with the calibrated turn, from their points' times: which changed.
  std::vector<bool> RedeskewKeyframes();
  // The odometry edges of a sequence (graph edge index, the registered
  // signed yaw of the same keyframe pair) rescaled by the sequence's factor.
  void CalibrateOdometryYaw(const std::map<std::string, std::vector<std::pair<size_t, double>>>& odometry_edges);
  int AddLoopEdges();
  void AddLoopEdge(const Keyframe& a, const Keyframe& b, const RegistrationResult& fine);
  void Optimize();
  int JoinComponents(int round);
  bool TryJoin(int A, int B, int round);
  // The steps of TryJoin (slam_join.cc), on one search's state.
  struct JoinSearch;
  struct JoinPlan;
  const Keyframe* NearestKeyframe(const std::vector<const Keyframe*>& part, const Eigen::Vector3d& p) const;
  std::vector<const Keyframe*> NearStart(const std::vector<const Keyframe*>& part, const Eigen::Vector3d& p0) const;
  void AddJoinCandidate(JoinSearch& s, const Keyframe& a, const Keyframe& b, const RegistrationResult& r,
                        bool predicted, bool precise) const;
  void QueueRoughCheck(JoinSearch& s, const Keyframe& a, const Keyframe& b, const std::vector<Pose>& guesses);
  void RunRoughQueue(JoinSearch& s);
  void QueueSeeds(JoinSearch& s, const std::vector<double>& yaws);
  void QueuePlaces(JoinSearch& s);
  JoinDecision JudgeFrames(JoinSearch& s);
  const JoinPlan& PlanOf(JoinSearch& s, int hypothesis);
  void MakeLoopsPrecise(JoinSearch& s, int hypothesis);
  size_t TestPredictedLoops(JoinSearch& s, const Pose& H);
  void ApplyJoin(JoinSearch& s, const JoinPlan& p);
  void RunJoinTrials(JoinSearch& s, JoinDecision* d);
  bool FinishJoin(JoinSearch& s, JoinDecision d);
  std::vector<Eigen::Vector3d> SequenceStarts(const std::vector<const Keyframe*>& part) const;
  std::vector<const Keyframe*> KeyframesOf(int component) const;
  std::string NameOf(int component) const;
  const FloorGrid& FloorOf(int component);
  void CheckFinalJoins();

  const SlamOptions& o_;
  const WheelOdometry* odometry_;
  MotionModel motion_;
  Registrar registrar_, refine_registrar_;
  std::vector<std::pair<Registrar, Registrar>> workers_;
  int threads_;
  SlamHooks hooks_;
  std::vector<Keyframe> keyframes_;  // sequences in time order, each in time order
  PoseGraph graph_, before_;
  std::set<std::pair<int, int>> accepted_;  // loop edges added (min id, max id)
  // Sequences sharing a frame: sequence -> component (id of its first keyframe).
  std::map<std::string, int> component_;
  std::set<std::string> manual_;  // sequences placed by initial_poses
  std::map<std::pair<int, int>, std::pair<size_t, size_t>> join_failed_;  // (A, B) -> their sizes then
  std::map<int, std::pair<int, FloorGrid>> floors_;  // component -> (poses version, grid)
  int poses_version_ = 0;
  std::vector<JoinAttempt> attempts_;
  std::vector<SequenceJoin> sequence_joins_;
  SlamStats stats_;
  std::mutex stats_mutex_;  // the counters Refine updates from worker threads
  // Clouds read from part files: keyframe id -> (last use, cloud).
  mutable std::mutex clouds_mutex_;
  mutable std::map<int, std::pair<uint64_t, std::shared_ptr<const Cloud>>> clouds_read_;
  mutable uint64_t clouds_clock_ = 0;
};

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_H_

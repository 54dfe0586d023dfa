#include "slam_output.h"

#include <cmath>
#include <set>
#include <sstream>

#include "locforge/kapture/io.h"
#include "plot.h"

namespace locforge::lidar {

namespace {

std::string Evidence(const JoinEvidence& e) {
  std::ostringstream s;
  s.precision(4);
  s << e.Agreeing() << "," << e.Conflict() << "," << e.b_in_a.agreeing << "," << e.b_in_a.conflicting << ","
    << e.a_in_b.agreeing << "," << e.a_in_b.conflicting;
  return s.str();
}

std::string EvidenceJson(const JoinEvidence& e) {
  std::ostringstream s;
  s.precision(6);
  s << "{\"agreeing\": " << e.Agreeing() << ", \"conflict\": " << e.Conflict() << ", \"b_in_a\": ["
    << e.b_in_a.agreeing << ", " << e.b_in_a.conflicting << ", " << e.b_in_a.unseen << "], \"a_in_b\": ["
    << e.a_in_b.agreeing << ", " << e.a_in_b.conflicting << ", " << e.a_in_b.unseen << "]}";
  return s.str();
}

std::string Quoted(const std::string& s) {
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

}  // namespace

// "\"map_00\": 0.98, ..." (a sequence's factor, 1 when not calibrated).
std::string YawScalesJson(const std::map<std::string, double>& scales) {
  std::ostringstream j;
  j.precision(8);
  for (const auto& [sequence, k] : scales) j << (j.tellp() > 0 ? ", " : "") << "\"" << sequence << "\"" << ": " << k;
  return j.str();
}

std::string JoinsCsv(const Slam& slam) {
  std::ostringstream s;
  s << "# Where every sequence ended up. status: anchor (its frame is the output's), joined, manual "
       "(initial_poses), separate (not joined: not in trajectories.txt). final_*: the sequence's map against "
       "the rest of its part after optimisation (cells of 0.1 m agreeing, fraction in the other's free space).\n";
  s << "sequence,status,part,round,consistent,final_agreeing,final_conflict,final_b_in_a_agreeing,"
       "final_b_in_a_conflicting,final_a_in_b_agreeing,final_a_in_b_conflicting\n";
  for (const auto& j : slam.sequence_joins())
    s << j.sequence << "," << j.status << "," << j.component << "," << j.round << "," << (j.consistent ? 1 : 0)
      << "," << Evidence(j.final_evidence) << "\n";
  s << "# Attempts: part b to part a; the best frame and its closest distinct rival (when any), with the evidence "
       "the decision used (once joined and optimised, for a frame tried on trial).\n";
  s << "# round,a,b,result,loops,frames,best_agreeing,best_conflict,best_b_in_a_agreeing,best_b_in_a_conflicting,"
       "best_a_in_b_agreeing,best_a_in_b_conflicting,rival_agreeing,rival_conflict,rival_b_in_a_agreeing,"
       "rival_b_in_a_conflicting,rival_a_in_b_agreeing,rival_a_in_b_conflicting,predicted_found,predicted_tested,"
       "reason\n";
  const JoinEvidence none;
  for (const auto& at : slam.join_attempts())
    s << "# " << at.round << "," << at.a << "," << at.b << "," << ToString(at.status) << "," << at.candidates << ","
      << at.hypotheses << "," << Evidence(at.winner >= 0 ? JoinAttempt::Decisive(at.frames[at.winner]) : none) << ","
      << Evidence(at.rival >= 0 ? JoinAttempt::Decisive(at.frames[at.rival]) : none) << "," << at.predicted_found << ","
      << at.predicted_tested << "," << Quoted(at.reason) << "\n";
  return s.str();
}

std::string UnjoinedMessage(const Slam& slam) {
  std::ostringstream s;
  std::vector<std::string> separate, inconsistent;
  for (const auto& j : slam.sequence_joins()) {
    if (j.status == "separate") separate.push_back(j.sequence);
    if (!j.consistent) inconsistent.push_back(j.sequence);
  }
  if (!inconsistent.empty()) {
    s << "the joined map does not hold: after optimisation the map of";
    for (const auto& q : inconsistent) s << " " << q;
    s << " puts structure into the free space of the rest of its part (joins.csv below). A join or a loop is wrong; "
         "give the start poses of these sequences with initial_poses to check them.";
  }
  if (!separate.empty()) {
    if (!inconsistent.empty()) s << " Also, ";
    s << "sequence(s)";
    for (const auto& q : separate) s << " " << q;
    s << " could not be joined to " << slam.keyframes().front().sequence
      << " with certainty (attempts below). Give each start pose in the first sequence's frame, e.g. --set "
         "'slam.initial_poses=[SEQUENCE X_M Y_M YAW_DEG]' (rough values do: the loops refine them), or set "
         "unjoined: separate to keep them out of the merged frame.";
  }
  for (const auto& at : slam.join_attempts())
    if (at.status != JoinDecision::Status::kJoined)
      s << "\n  round " << at.round << ": " << at.b << " to " << at.a << ": " << ToString(at.status) << ": "
        << at.reason;
  return s.str();
}

namespace {

// Only the anchor's part: a part not joined lives in another frame.
bool InAnchor(const Slam& slam, bool found, const Keyframe* from) {
  return found && from && slam.ComponentOf(from->sequence) == slam.AnchorComponent();
}

// The rig at every scan and the cameras at every image, of the anchor's
// part: trajectory interpolation (odometry between keyframes) x rig
// extrinsics (T_camera_world = T_camera_rig T_rig_world).
kapture::Trajectories AnchorTrajectories(const Slam& slam, const std::vector<kapture::DataRecord>& scans,
                                         const kapture::Kapture& dataset, int64_t* camera_poses) {
  kapture::Trajectories trajectories;
  for (const auto& r : scans) {
    bool found = false;
    const Keyframe* from = nullptr;
    const Pose T_world_rig = slam.PoseAt(r.timestamp, &found, &from);
    if (InAnchor(slam, found, from)) trajectories.Set(r.timestamp, "rig", T_world_rig.Inverse());
  }
  if (!dataset.HasRecords(kapture::kSensorCamera)) return trajectories;
  dataset.ForEachDataRecord(kapture::kSensorCamera, [&](const kapture::DataRecord& r) {
    const kapture::Rig* rig = dataset.rigs().RigOf(r.device_id);
    const kapture::RigSensor* rs = rig ? rig->Find(r.device_id) : nullptr;
    if (!rs) return;
    bool found = false;
    const Keyframe* from = nullptr;
    const Pose T_world_rig = slam.PoseAt(r.timestamp, &found, &from);
    if (!InAnchor(slam, found, from)) return;
    trajectories.Set(r.timestamp, r.device_id, rs->sensor_from_rig * T_world_rig.Inverse());
    ++*camera_poses;
  });
  return trajectories;
}

// The anchor part's keyframes at their optimised poses, downsampled.
Cloud AnchorMap(const Slam& slam, double voxel_m) {
  VoxelAccumulator map(voxel_m);  // one keyframe's cloud in memory at a time
  for (const auto& kf : slam.keyframes()) {
    if (slam.ComponentOf(kf.sequence) != slam.AnchorComponent()) continue;
    Cloud c = *slam.CloudOf(kf);
    Transform(slam.graph().nodes.at(kf.id), &c);
    map.Add(c);
  }
  return map.Result();
}

// The keyframes top-down before and after optimisation, with the loops.
void WriteTrajectoryPlot(const Slam& slam, const fs::path& stem) {
  const PoseGraph& graph = slam.graph();
  std::vector<PlotSequence> plot_before, plot_after;
  std::vector<std::pair<int, int>> loops;
  for (const auto& e : graph.edges)
    if (e.loop) loops.emplace_back(e.from, e.to);
  for (const auto& kf : slam.keyframes()) {
    if (plot_after.empty() || plot_after.back().name != kf.sequence) {
      plot_before.push_back({kf.sequence, {}, {}});
      plot_after.push_back({kf.sequence, {}, {}});
    }
    plot_before.back().ids.push_back(kf.id);
    plot_before.back().xy.push_back(slam.initial_graph().nodes.at(kf.id).t.head<2>());
    plot_after.back().ids.push_back(kf.id);
    plot_after.back().xy.push_back(graph.nodes.at(kf.id).t.head<2>());
  }
  WriteTopDown(stem, plot_before, plot_after, loops);
}

// slam.json's "loops": each loop edge's keyframes, times and positions.
std::string LoopsJson(const Slam& slam) {
  const PoseGraph& graph = slam.graph();
  const auto& keyframes = slam.keyframes();
  std::ostringstream loops_json;
  loops_json.precision(16);
  for (const auto& e : graph.edges) {
    if (!e.loop) continue;
    const Keyframe& a = keyframes[e.from];
    const Keyframe& b = keyframes[e.to];
    const Eigen::Vector3d pa = graph.nodes.at(a.id).t, pb = graph.nodes.at(b.id).t;
    loops_json << (loops_json.tellp() > 0 ? ",\n    " : "\n    ") << "{\"from\": " << a.id << ", \"to\": " << b.id
               << ", \"from_time\": " << a.timestamp << ", \"to_time\": " << b.timestamp << ", \"from_xy\": ["
               << pa.x() << ", " << pa.y() << "], \"to_xy\": [" << pb.x() << ", " << pb.y() << "]}";
  }
  return loops_json.str();
}

// One join attempt's frames (joins_json: the stream it is written into).
void WriteJoinFrames(const JoinAttempt& at, std::ostringstream& joins_json) {
  for (size_t i = 0; i < at.frames.size(); ++i) {
    const JoinHypothesis& h = at.frames[i];
    joins_json << (i ? ", " : "") << "{\"x\": " << h.T_A_B.t.x() << ", \"y\": " << h.T_A_B.t.y()
               << ", \"z\": " << h.T_A_B.t.z() << ", \"yaw_deg\": " << YawOf(h.T_A_B) * 180.0 / M_PI
               << ", \"start_offset_m\": " << h.start_offset_m << ", \"support\": " << h.support
               << ", \"evidence\": " << EvidenceJson(h.evidence);
    if (h.tried) joins_json << ", \"on_trial\": " << EvidenceJson(h.after);
    joins_json << "}";
  }
}

// slam.json's "join_attempts_detail".
std::string JoinsJson(const Slam& slam) {
  std::ostringstream joins_json;
  for (const auto& at : slam.join_attempts()) {
    joins_json << (joins_json.tellp() > 0 ? ",\n    " : "\n    ") << "{\"round\": " << at.round << ", \"a\": \""
               << at.a << "\", \"b\": \"" << at.b << "\", \"result\": \"" << ToString(at.status)
               << "\", \"loops\": " << at.candidates << ", \"frames\": " << at.hypotheses;
    if (at.winner >= 0) joins_json << ", \"best\": " << EvidenceJson(JoinAttempt::Decisive(at.frames[at.winner]));
    if (at.rival >= 0) joins_json << ", \"rival\": " << EvidenceJson(JoinAttempt::Decisive(at.frames[at.rival]));
    joins_json << ", \"predicted_found\": " << at.predicted_found << ", \"predicted_tested\": " << at.predicted_tested
               << ", \"frames\": [";
    WriteJoinFrames(at, joins_json);
    joins_json << "]}";
  }
  return joins_json.str();
}

std::string StepsJson(const StepTimes& steps) {
  std::ostringstream steps_json;
  steps_json.precision(6);
  for (const auto& [name, t] : steps)
    steps_json << (steps_json.tellp() > 0 ? ", " : "") << "\"" << name << "\": " << t;
  return steps_json.str();
}

// What slam.json counts besides the slam's own statistics.
struct OutputCounts {
  size_t scans = 0, sequences = 0, map_points = 0;
  int loop_edges = 0, cross = 0;  // loop edges, those across sequences
  int64_t camera_poses = 0;
};

OutputCounts CountLoops(const Slam& slam) {
  OutputCounts n;
  for (const auto& e : slam.graph().edges) {
    if (!e.loop) continue;
    ++n.loop_edges;
    if (slam.keyframes()[e.from].sequence != slam.keyframes()[e.to].sequence) ++n.cross;
  }
  std::set<std::string> sequences;
  for (const auto& kf : slam.keyframes()) sequences.insert(kf.sequence);
  n.sequences = sequences.size();
  return n;
}

std::string SlamJson(const Slam& slam, const SlamOptions& o, const OutputCounts& n, const PlaneResidualStats& crisp,
                     const std::string& steps_json, double seconds) {
  const SlamStats& st = slam.stats();
  std::ostringstream j;
  j.precision(10);
  j << "{\n  \"scans\": " << n.scans << ",\n  \"keyframes\": " << slam.keyframes().size()
    << ",\n  \"sequences\": " << n.sequences << ",\n  \"sequential_edges\": "
    << slam.graph().edges.size() - n.loop_edges << ",\n  \"sequential_odometry_fallbacks\": " << st.sequential_fallbacks
    << ",\n  \"loop_edges\": " << n.loop_edges << ",\n  \"cross_sequence_loop_edges\": " << n.cross
    << ",\n  \"loop_candidates_tested\": " << st.loop_tests << ",\n  \"joins\": " << st.joins
    << ",\n  \"join_attempts\": " << st.join_attempts << ",\n  \"join_candidates_tested\": " << st.join_tests
    << ",\n  \"odometry_yaw_scale\": {" << YawScalesJson(st.odometry_yaw_scale) << "}"
    << ",\n  \"sequential_reregistered\": " << st.sequential_reregistered
    << ",\n  \"join_trials\": " << st.join_trials << ",\n  \"join_rejected_loops\": " << st.join_rejected_loops << ",\n  \"initial_cost\": " << st.summary.initial_cost
    << ",\n  \"final_cost\": " << st.summary.final_cost << ",\n  \"camera_poses\": " << n.camera_poses
    << ",\n  \"information_fallbacks\": " << st.information_fallbacks << ",\n  \"refinements\": " << st.refinements
    << ",\n  \"refinements_rejected\": " << st.refinements_rejected << ",\n  \"map_points\": " << n.map_points
    << ",\n  \"map_plane_residual\": {\"k\": " << o.map_residual_k << ", \"radius\": " << o.map_residual_radius_m
    << ", \"stride\": " << o.map_residual_stride
    << ", \"points\": " << crisp.points << ", \"skipped\": " << crisp.skipped << ", \"mean\": " << crisp.mean
    << ", \"median\": " << crisp.median << ", \"rmse\": " << crisp.rmse << ", \"p90\": " << crisp.p90 << "}"
    << ",\n  \"join_attempts_detail\": [" << JoinsJson(slam) << "\n  ]"
    << ",\n  \"loops\": [" << LoopsJson(slam) << "\n  ]"
    << ",\n  \"step_seconds\": {" << steps_json << "}"
    << ",\n  \"seconds\": " << seconds
    << ",\n  \"scans_per_second\": " << n.scans / std::max(seconds, 1e-9) << "\n}\n";
  return j.str();
}

}  // namespace

std::string WriteSlamOutputs(const Slam& slam, const SlamOptions& o,
                             const std::vector<kapture::DataRecord>& scans, const kapture::Kapture& dataset,
                             const fs::path& out, std::chrono::steady_clock::time_point start) {
  const auto outputs_start = std::chrono::steady_clock::now();
  OutputCounts n = CountLoops(slam);
  n.scans = scans.size();
  const kapture::Trajectories trajectories = AnchorTrajectories(slam, scans, dataset, &n.camera_poses);
  kapture::WriteTrajectories(out / kapture::layout::kTrajectories, trajectories);
  kapture::WriteSensors(out / kapture::layout::kSensors, dataset.sensors());
  if (!dataset.rigs().empty()) kapture::WriteRigs(out / kapture::layout::kRigs, dataset.rigs());
  WriteFileAtomic(out / "joins.csv", JoinsCsv(slam));

  const Cloud map = AnchorMap(slam, o.map_voxel_m);
  n.map_points = map.size();
  WritePcd(out / "map.pcd", map);
  WritePly(out / "map.ply", map);
  WriteG2o(out / "pose_graph.g2o", slam.graph());
  WriteTrajectoryPlot(slam, out / "trajectories");

  const PlaneResidualStats crisp = MapPlaneResidual(map, o.map_residual_k, o.map_residual_radius_m, slam.threads(),
                                                     o.map_residual_stride);
  StepTimes steps = slam.stats().steps;
  const auto now = std::chrono::steady_clock::now();
  steps.emplace_back("outputs", std::chrono::duration<double>(now - outputs_start).count());
  const double seconds = std::chrono::duration<double>(now - start).count();
  WriteFileAtomic(out / "slam.json", SlamJson(slam, o, n, crisp, StepsJson(steps), seconds));
  return std::to_string(n.loop_edges) + " loop edges (" + std::to_string(n.cross) + " across sequences), " +
         slam.stats().summary.report;
}

}  // namespace locforge::lidar

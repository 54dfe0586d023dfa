// eval/joins: how the sequences of a multi-sequence LiDAR map were put in one
// frame, against a simulated recording's truth. For every sequence: right,
// wrong or refused (not in the merged frame), its error after ONE rigid
// alignment of the whole recording, its own-alignment error (the drift left
// inside it), RPE over 1 m and its scale against the truth.
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "locforge/units.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "locforge/kapture/csv.h"
#include "metrics.h"

namespace locforge::eval {

namespace {

struct JoinsEvalOptions {
  std::string device = "rig";
  double seconds_per_unit = kDefaultSecondsPerUnit;
  double max_diff_s = 0.001;  // association of poses
  double wrong_translation_m = 0.25;
  double wrong_rotation_deg = 1.0;
  static void Declare(ParamSchema<JoinsEvalOptions>& s) {
    using O = JoinsEvalOptions;
    s.Add("device", &O::device, "kapture device evaluated (the platform rig)");
    AddSecondsPerUnit(s, &O::seconds_per_unit);
    s.Add("max_diff_s", &O::max_diff_s, "Largest timestamp difference of associated poses (s)").Min(0);
    s.Add("wrong_translation_m", &O::wrong_translation_m,
          "A joined sequence is wrong when the rigid alignment of its own poses and the first sequence's differ "
          "by more than this over its poses (m RMS) ...").Min(1e-6);
    s.Add("wrong_rotation_deg", &O::wrong_rotation_deg, "... or by more than this rotation (deg)").Min(1e-6);
  }
};

class JoinsEval : public Stage<JoinsEvalOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"eval", "joins",
            "Joins of a multi-sequence LiDAR map against a simulated truth: right / wrong / refused per sequence, "
            "whole-recording ATE after one rigid alignment",
            {{"estimate", "kapture.trajectories", "slam/pose_graph output (trajectories.txt, joins.csv)"},
             {"reference", "kapture.dataset",
              "the simulated recording: sensors/trajectories.txt (truth), truth/sequences.txt (each sequence's "
              "time span)"}},
            {{"report", "report", "joins_eval.csv (per sequence), summary.json, report.md"}}};
    meta.version = "0.2.1";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

struct SequenceSpan {
  std::string name;
  double t0 = 0, t1 = 0;  // s
};

std::vector<SequenceSpan> ReadSequences(const fs::path& file) {
  std::vector<SequenceSpan> out;
  std::ifstream in(file);
  if (!in) throw InputError(file.string(), 0, "", "cannot read (a simulated recording's truth/sequences.txt)");
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.empty() || line[0] == '#') continue;
    const std::vector<std::string> f = kapture::SplitCsvLine(line);
    if (f.size() < 5) throw InputError(file.string(), n, "", "expected name, split, day, t0_us, duration_s, ...");
    try {
      const double t0 = std::stod(f[3]) * 1e-6;
      out.push_back({f[0], t0, t0 + std::stod(f[4])});
    } catch (const std::exception&) {
      throw InputError(file.string(), n, "t0_us", "not a number: '" + f[3] + "'");
    }
  }
  return out;
}

std::map<std::string, std::string> ReadJoinStatus(const fs::path& file) {
  std::map<std::string, std::string> out;
  std::ifstream in(file);
  if (!in) return out;
  std::string line;
  bool header = true;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (header) {
      header = false;
      continue;
    }
    std::stringstream s(line);
    std::string seq, status;
    std::getline(s, seq, ',');
    std::getline(s, status, ',');
    out[seq] = status;
  }
  return out;
}

// Positions plus points 1 m along each pose's x and z axes: a planar path's
// positions alone leave a mirror-like flip free for a wrong map.
std::vector<Eigen::Vector3d> Augmented(const Trajectory& t) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : t) {
    const Eigen::Matrix3d R = p.T_world_device.q.toRotationMatrix();
    out.push_back(p.T_world_device.t);
    out.push_back(p.T_world_device.t + R.col(0));
    out.push_back(p.T_world_device.t + R.col(2));
  }
  return out;
}

Trajectory Aligned(const Trajectory& t, const Similarity& s) {
  Trajectory out = t;
  for (auto& p : out) {
    p.T_world_device = Pose(Eigen::Quaterniond(s.R) * p.T_world_device.q, s.scale * (s.R * p.T_world_device.t) + s.t);
    p.raw.reset();
  }
  return out;
}

Similarity RigidFit(const Trajectory& reference, const Trajectory& estimate) {
  return Umeyama(Augmented(estimate), Augmented(reference), false);
}

struct SequenceResult {
  std::string name, status, verdict;
  size_t poses = 0;
  Statistics whole_t, whole_r, own_t, own_r, rpe_t, rpe_r;
  double scale = 1, offset_t = 0, offset_r = 0;
  double yaw_bias_deg = 0;  // mean signed heading error in the whole alignment
};

// Mean signed heading (yaw) of est against ref, wrapped to (-180, 180].
double YawBiasDeg(const Trajectory& ref, const Trajectory& est) {
  double sum = 0;
  for (size_t i = 0; i < ref.size(); ++i) {
    const Eigen::Matrix3d R = ref[i].T_world_device.q.toRotationMatrix().transpose() *
                              est[i].T_world_device.q.toRotationMatrix();
    sum += std::atan2(R(1, 0), R(0, 0));
  }
  return ref.empty() ? 0.0 : sum / static_cast<double>(ref.size()) * 180 / M_PI;
}

using BySequence = std::map<std::string, std::pair<Trajectory, Trajectory>>;  // name -> (reference, estimate)

// The associated poses split by the sequence whose time span holds them.
BySequence SplitBySequence(const Trajectory& reference, const Trajectory& estimate,
                           const std::vector<SequenceSpan>& spans) {
  BySequence by_seq;
  for (size_t i = 0; i < estimate.size(); ++i)
    for (const auto& s : spans)
      if (estimate[i].time >= s.t0 - 1e-6 && estimate[i].time <= s.t1 + 1e-6) {
        by_seq[s.name].first.push_back(reference[i]);
        by_seq[s.name].second.push_back(estimate[i]);
      }
  return by_seq;
}

// The first sequence with poses: the anchor of the merged frame, which fixes
// the frame the joins are judged in.
std::string AnchorOf(const std::vector<SequenceSpan>& spans, const BySequence& by_seq) {
  for (const auto& s : spans)
    if (by_seq.count(s.name)) return s.name;
  return "";
}

// A joined sequence's errors in the whole alignment, in its own, RPE and
// scale, and its verdict: right when its own alignment and the anchor's
// agree within the options' bounds.
void Judge(const Trajectory& rs, const Trajectory& es, const Similarity& whole, const Similarity& anchor_fit,
           const JoinsEvalOptions& o, SequenceResult* r) {
  r->poses = es.size();
  const Errors in_whole = AbsolutePoseErrors(rs, Aligned(es, whole));
  r->yaw_bias_deg = YawBiasDeg(rs, Aligned(es, whole));
  r->whole_t = ComputeStatistics(in_whole.translation);
  r->whole_r = ComputeStatistics(in_whole.rotation);
  const Similarity own = RigidFit(rs, es);
  const Errors in_own = AbsolutePoseErrors(rs, Aligned(es, own));
  r->own_t = ComputeStatistics(in_own.translation);
  r->own_r = ComputeStatistics(in_own.rotation);
  const Errors rpe = RelativePoseErrors(rs, es, 1.0, DeltaUnit::kMeters);
  r->rpe_t = ComputeStatistics(rpe.translation);
  r->rpe_r = ComputeStatistics(rpe.rotation);
  r->scale = Umeyama(Augmented(es), Augmented(rs), true).scale;
  // The sequence under the anchor's alignment against under its own.
  const Errors offset = AbsolutePoseErrors(Aligned(es, own), Aligned(es, anchor_fit));
  r->offset_t = ComputeStatistics(offset.translation).rmse;
  r->offset_r = ComputeStatistics(offset.rotation).rmse;
  const bool off = r->offset_t > o.wrong_translation_m || r->offset_r > o.wrong_rotation_deg;
  r->verdict = off ? "wrong" : "right";
}

struct Tally {
  int right = 0, wrong = 0, refused = 0;
};

std::vector<SequenceResult> JudgeSequences(const std::vector<SequenceSpan>& spans, BySequence& by_seq,
                                           const std::map<std::string, std::string>& status, const Similarity& whole,
                                           const JoinsEvalOptions& o, Tally* tally) {
  const std::string anchor = AnchorOf(spans, by_seq);
  const Similarity anchor_fit = RigidFit(by_seq[anchor].first, by_seq[anchor].second);
  std::vector<SequenceResult> results;
  for (const auto& s : spans) {
    SequenceResult r;
    r.name = s.name;
    r.status = status.count(s.name) ? status.at(s.name) : (by_seq.count(s.name) ? "unknown" : "absent");
    const auto it = by_seq.find(s.name);
    if (it == by_seq.end() || it->second.second.size() < 3) {
      r.verdict = "refused";
      ++tally->refused;
    } else {
      Judge(it->second.first, it->second.second, whole, anchor_fit, o, &r);
      (r.verdict == "wrong" ? tally->wrong : tally->right) += 1;
    }
    results.push_back(r);
  }
  return results;
}

// Every other device both hold (the cameras), in the rig's one alignment:
// the camera poses a user of the ground truth gets.
Errors CameraErrors(const fs::path& estimate, const fs::path& reference, const JoinsEvalOptions& o,
                    const Similarity& whole, size_t* devices_used) {
  Errors camera_errors;
  const kapture::Trajectories est_all = kapture::ReadTrajectories(estimate / kapture::layout::kTrajectories);
  const kapture::Trajectories ref_all = kapture::ReadTrajectories(reference / kapture::layout::kTrajectories);
  std::set<std::string> devices;
  for (const auto& [key, pose] : est_all.poses)
    if (key.second != o.device && ref_all.poses.count(key)) devices.insert(key.second);
  for (const std::string& d : devices) {
    Trajectory re, ee;
    for (const auto& [key, pose] : est_all.poses) {
      if (key.second != d) continue;
      const auto it = ref_all.poses.find(key);
      if (it == ref_all.poses.end()) continue;
      re.push_back({key.first * o.seconds_per_unit, it->second.Inverse()});
      ee.push_back({key.first * o.seconds_per_unit, pose.Inverse()});
    }
    const Errors e = AbsolutePoseErrors(re, Aligned(ee, whole));
    camera_errors.translation.insert(camera_errors.translation.end(), e.translation.begin(), e.translation.end());
    camera_errors.rotation.insert(camera_errors.rotation.end(), e.rotation.begin(), e.rotation.end());
    ++*devices_used;
  }
  return camera_errors;
}

std::string ResultsCsv(const std::vector<SequenceResult>& results) {
  std::ostringstream csv;
  csv.precision(6);
  csv << "sequence,status,verdict,poses,ate_whole_m,rot_whole_deg,ate_own_m,rot_own_deg,rpe_1m_m,rpe_1m_deg,"
         "yaw_bias_deg,scale,offset_to_first_m,offset_to_first_deg\n";
  for (const auto& r : results)
    csv << r.name << "," << r.status << "," << r.verdict << "," << r.poses << "," << r.whole_t.rmse << ","
        << r.whole_r.rmse << "," << r.own_t.rmse << "," << r.own_r.rmse << "," << r.rpe_t.rmse << "," << r.rpe_r.rmse
        << "," << r.yaw_bias_deg << "," << r.scale << "," << r.offset_t << "," << r.offset_r << "\n";
  return csv.str();
}

// The whole recording's errors: the rig's (w: translation, rotation) and the cameras' (c).
struct WholeErrors {
  size_t poses = 0, camera_devices = 0;
  Statistics wt, wr, ct, cr;
};

std::string ReportMd(const std::vector<SequenceResult>& results, const WholeErrors& e, const std::string& device) {
  std::ostringstream md;
  md.precision(4);
  md << "# Joins against the truth\n\n" << e.poses << " poses of `" << device << "`; one rigid alignment "
     << "of the whole recording: ATE " << e.wt.rmse * 100 << " cm RMS, " << e.wr.rmse << " deg RMS";
  if (e.camera_devices > 0)
    md << "; camera poses (" << e.camera_devices << " cameras, " << e.ct.count << " poses, same alignment): "
       << e.ct.rmse * 100 << " cm RMS, " << e.cr.rmse << " deg RMS";
  md << ".\n\n"
     << "| sequence | status | verdict | ATE whole (cm) | rot whole (deg) | heading bias (deg) | ATE own (cm) | "
        "RPE 1 m (cm) | scale |\n"
     << "|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : results)
    md << "| " << r.name << " | " << r.status << " | " << r.verdict << " | " << r.whole_t.rmse * 100 << " | "
       << r.whole_r.rmse << " | " << r.yaw_bias_deg << " | " << r.own_t.rmse * 100 << " | " << r.rpe_t.rmse * 100 << " | " << r.scale << " |\n";
  return md.str();
}

std::string SummaryJson(size_t sequences, const Tally& t, const WholeErrors& e) {
  std::ostringstream json;
  json.precision(8);
  const bool fully = t.refused == 0 && t.wrong == 0;
  json << "{\n  \"sequences\": " << sequences << ",\n  \"right\": " << t.right << ",\n  \"wrong\": " << t.wrong
       << ",\n  \"refused\": " << t.refused << ",\n  \"fully_joined\": " << (fully ? "true" : "false")
       << ",\n  \"poses\": " << e.poses << ",\n  \"ate_whole_m\": " << e.wt.rmse
       << ",\n  \"ate_whole_max_m\": " << e.wt.max << ",\n  \"rotation_whole_deg\": " << e.wr.rmse
       << ",\n  \"camera_poses\": " << e.ct.count << ",\n  \"camera_ate_whole_m\": " << e.ct.rmse
       << ",\n  \"camera_rotation_whole_deg\": " << e.cr.rmse << "\n}\n";
  return json.str();
}

}  // namespace

void JoinsEval::Run(RunContext& ctx) {
  const JoinsEvalOptions& o = options();
  const fs::path ref = ctx.Input("reference");
  Trajectory estimate = ReadKaptureTrajectory(ctx.Input("estimate"), o.device, o.seconds_per_unit);
  Trajectory reference = ReadKaptureTrajectory(ref, o.device, o.seconds_per_unit);
  Associate(o.max_diff_s, &reference, &estimate);
  const std::vector<SequenceSpan> spans = ReadSequences(ref / "truth" / "sequences.txt");
  const std::map<std::string, std::string> status = ReadJoinStatus(ctx.Input("estimate") / "joins.csv");
  BySequence by_seq = SplitBySequence(reference, estimate, spans);
  if (estimate.size() < 3) throw Error("eval/joins: fewer than 3 poses of the estimate match the reference");
  const Similarity whole = RigidFit(reference, estimate);
  const Errors whole_errors = AbsolutePoseErrors(reference, Aligned(estimate, whole));
  Tally tally;
  const std::vector<SequenceResult> results = JudgeSequences(spans, by_seq, status, whole, o, &tally);
  WholeErrors e;
  e.poses = estimate.size();
  e.wt = ComputeStatistics(whole_errors.translation);
  e.wr = ComputeStatistics(whole_errors.rotation);
  const Errors camera_errors = CameraErrors(ctx.Input("estimate"), ref, o, whole, &e.camera_devices);
  e.ct = ComputeStatistics(camera_errors.translation);
  e.cr = ComputeStatistics(camera_errors.rotation);
  const fs::path out = ctx.output_dir();
  WriteFileAtomic(out / "joins_eval.csv", ResultsCsv(results));
  WriteFileAtomic(out / "report.md", ReportMd(results, e, o.device));
  WriteFileAtomic(out / "summary.json", SummaryJson(results.size(), tally, e));
  std::ostringstream line;
  line.precision(3);
  line << "eval/joins: " << tally.right << " right, " << tally.wrong << " wrong, " << tally.refused
       << " refused; whole recording ATE " << e.wt.rmse * 100 << " cm, " << e.wr.rmse << " deg RMS";
  if (e.camera_devices > 0) line << "; cameras " << e.ct.rmse * 100 << " cm, " << e.cr.rmse << " deg";
  ctx.Info(line.str());
}

LOCFORGE_REGISTER_STAGE(JoinsEval)

}  // namespace locforge::eval

// eval/trajectory: ATE (APE) and RPE of an estimated kapture trajectory
// against a reference (kapture, TUM or KITTI), evo-compatible (metrics.h),
// with a Markdown/CSV/JSON report and TUM/KITTI exports.
#include <sstream>

#include "locforge/units.h"
#include "locforge/plugin.h"
#include "metrics.h"

namespace locforge::eval {

struct TrajectoryEvalOptions {
  std::string reference;              // kapture folder, TUM or KITTI file
  std::string reference_format = "auto";
  std::string device = "rig";         // kapture device evaluated
  double seconds_per_unit = kDefaultSecondsPerUnit;
  std::string alignment = "none";
  double max_diff_s = 0.01;  // timestamp association
  double rpe_delta = 1;
  std::string rpe_unit = "meters";
  bool rpe_all_pairs = false;
  static void Declare(ParamSchema<TrajectoryEvalOptions>& s) {
    using O = TrajectoryEvalOptions;
    s.Add("reference", &O::reference,
          "Reference trajectory: kapture folder, TUM or KITTI file (or wire the reference input)").Path();
    s.Add("reference_format", &O::reference_format, "Format of the reference").Choices({"auto", "kapture", "tum", "kitti"});
    s.Add("device", &O::device, "kapture device evaluated (estimate and kapture reference)");
    AddSecondsPerUnit(s, &O::seconds_per_unit);
    s.Add("alignment", &O::alignment, "Alignment of the estimate: none, first pose, Umeyama SE(3) or Sim(3)")
        .Choices({"none", "first", "se3", "sim3"});
    s.Add("max_diff_s", &O::max_diff_s, "Largest timestamp difference of associated poses (s)").Min(0);
    s.Add("rpe_delta", &O::rpe_delta, "RPE step (frames or metres)").Min(1e-9);
    s.Add("rpe_unit", &O::rpe_unit, "Unit of rpe_delta").Choices({"frames", "meters"});
    s.Add("rpe_all_pairs", &O::rpe_all_pairs, "RPE over all pairs instead of consecutive ones");
  }
};

class TrajectoryEval : public Stage<TrajectoryEvalOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"eval", "trajectory", "ATE and RPE (translation, rotation) against a reference, evo-compatible",
            {{"estimate", "kapture.trajectories", "Estimated trajectory (sensors/trajectories.txt)"},
             {"reference", "kapture.dataset", "the reference kapture (e.g. a simulated recording), instead of the "
              "reference parameter", LF_PORT_OPTIONAL}},
            {{"report", "report", "report.md, metrics.csv, metrics.json, estimate/reference .tum and .kitti"}}};
    meta.version = "0.1.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

namespace {
Alignment ParseAlignment(const std::string& s) {
  return s == "first" ? Alignment::kFirst : s == "se3" ? Alignment::kSE3 : s == "sim3" ? Alignment::kSim3 : Alignment::kNone;
}
}  // namespace

void TrajectoryEval::Run(RunContext& ctx) {
  const TrajectoryEvalOptions& o = options();
  Trajectory estimate = ReadKaptureTrajectory(ctx.Input("estimate"), o.device, o.seconds_per_unit);
  std::string format = o.reference_format;
  const fs::path ref_path = ctx.PathOrInput("eval/trajectory", "reference", o.reference, "reference");
  if (format == "auto") format = fs::is_directory(ref_path) ? "kapture" : "tum";
  Trajectory reference = format == "kapture" ? ReadKaptureTrajectory(ref_path, o.device, o.seconds_per_unit)
                         : format == "kitti" ? ReadKitti(ref_path)
                                             : ReadTum(ref_path);
  const size_t estimate_poses = estimate.size();
  Associate(o.max_diff_s, &reference, &estimate);
  if (reference.size() < 2) throw Error("eval/trajectory: fewer than 2 associated poses");
  const Similarity s = Align(ParseAlignment(o.alignment), reference, &estimate);
  const Errors ape = AbsolutePoseErrors(reference, estimate);
  const Errors rpe = RelativePoseErrors(reference, estimate, o.rpe_delta,
                                        o.rpe_unit == "frames" ? DeltaUnit::kFrames : DeltaUnit::kMeters, o.rpe_all_pairs);
  const std::vector<std::pair<std::string, Statistics>> rows = {
      {"ape_translation_m", ComputeStatistics(ape.translation)},
      {"ape_rotation_deg", ComputeStatistics(ape.rotation)},
      {"rpe_translation_m", ComputeStatistics(rpe.translation)},
      {"rpe_rotation_deg", ComputeStatistics(rpe.rotation)}};
  std::ostringstream csv, md, json;
  csv.precision(10);
  md.precision(6);
  json.precision(17);
  csv << "metric,count,rmse,mean,median,std,min,max,sse\n";
  md << "# Trajectory evaluation\n\n" << estimate.size() << " associated poses (" << estimate_poses
     << " estimated), alignment " << o.alignment << " (scale " << s.scale << "), RPE delta " << o.rpe_delta << ' '
     << o.rpe_unit << "\n\n| metric | count | rmse | mean | median | std | min | max |\n|---|---|---|---|---|---|---|---|\n";
  json << "{\n  \"associated_poses\": " << estimate.size() << ",\n  \"alignment\": \"" << o.alignment
       << "\",\n  \"scale\": " << s.scale;
  for (const auto& [name, st] : rows) {
    csv << name << ',' << st.count << ',' << st.rmse << ',' << st.mean << ',' << st.median << ',' << st.std << ','
        << st.min << ',' << st.max << ',' << st.sse << '\n';
    md << "| " << name << " | " << st.count << " | " << st.rmse << " | " << st.mean << " | " << st.median << " | "
       << st.std << " | " << st.min << " | " << st.max << " |\n";
    json << ",\n  \"" << name << "\": {\"count\": " << st.count << ", \"rmse\": " << st.rmse << ", \"mean\": "
         << st.mean << ", \"median\": " << st.median << ", \"std\": " << st.std << ", \"min\": " << st.min
         << ", \"max\": " << st.max << ", \"sse\": " << st.sse << "}";
  }
  json << "\n}\n";
  const fs::path out = ctx.output_dir();
  WriteFileAtomic(out / "metrics.csv", csv.str());
  WriteFileAtomic(out / "report.md", md.str());
  WriteFileAtomic(out / "metrics.json", json.str());
  WriteFileAtomic(out / "estimate.tum", FormatTum(estimate));
  WriteFileAtomic(out / "reference.tum", FormatTum(reference));
  WriteFileAtomic(out / "estimate.kitti", FormatKitti(estimate));
  WriteFileAtomic(out / "reference.kitti", FormatKitti(reference));
  ctx.Info("eval/trajectory: APE rmse " + FormatDouble(rows[0].second.rmse) + " m, " +
           FormatDouble(rows[1].second.rmse) + " deg over " + std::to_string(estimate.size()) + " poses");
}

LOCFORGE_REGISTER_STAGE(TrajectoryEval)

}  // namespace locforge::eval

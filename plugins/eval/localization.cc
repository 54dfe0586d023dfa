// eval/localization: one method's localization errors, recalls and curve
// against the ground truth (library: localization/).
#include <map>
#include <regex>
#include <sstream>

#include "evaluation.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::eval {

using namespace ::locforge::evaluation;  // the library this stage wires

namespace {

namespace kp = locforge::kapture;

// "name=regex" list entries.
std::vector<std::pair<std::string, std::regex>> ParseLabelled(const std::vector<std::string>& items,
                                                              const std::string& param,
                                                              std::string* why) {
  std::vector<std::pair<std::string, std::regex>> out;
  for (const auto& item : items) {
    const size_t eq = item.find('=');
    if (eq == std::string::npos || eq == 0) {
      if (why) *why = param + ": '" + item + "' is not NAME=REGEX";
      return {};
    }
    try {
      out.emplace_back(item.substr(0, eq), std::regex(item.substr(eq + 1)));
    } catch (const std::regex_error& e) {
      if (why) *why = param + ": bad regex in '" + item + "': " + e.what();
      return {};
    }
  }
  return out;
}

std::string LabelOf(const std::vector<std::pair<std::string, std::regex>>& labels,
                    const std::string& text) {
  for (const auto& [name, re] : labels)
    if (std::regex_match(text, re)) return name;
  return labels.empty() ? "all" : "other";
}

struct EvalOptions {
  std::string method = "method";  // Row label of this method in the tables.
  std::vector<std::string> groups;  // Camera groups "NAME=REGEX" on the query device id.
  std::vector<std::string> splits;  // Splits "NAME=REGEX" on the query image path.
  std::vector<double> positions_m = {0.1, 0.25, 1.0};  // Position thresholds (<=).
  std::vector<double> angles_deg = {1.0, 2.0, 5.0};    // Angle thresholds (<=), paired.
  double curve_max_m = 1.0;  // Curve's largest position threshold (log axis over 3 decades); angle = 10 x position.

  static void Declare(ParamSchema<EvalOptions>& s) {
    s.Add("method", &EvalOptions::method, "row label of this method in the tables");
    s.Add("groups", &EvalOptions::groups, "camera groups NAME=REGEX matched on the query device id");
    s.Add("splits", &EvalOptions::splits, "splits NAME=REGEX matched on the query image path");
    s.Add("positions_m", &EvalOptions::positions_m, "position thresholds in metres (<=)");
    s.Add("angles_deg", &EvalOptions::angles_deg, "angle thresholds in degrees (<=), one per position");
    s.Add("curve_max_m", &EvalOptions::curve_max_m, "recall curve up to this position threshold, from 1/1000 of it on a log axis (angle = 10 x metres in degrees)").Min(0.01);
  }
  bool Check(std::string* why) const {
    if (positions_m.size() != angles_deg.size() || positions_m.empty())
      return *why = "positions_m and angles_deg need the same, non-zero length", false;
    for (size_t i = 0; i < positions_m.size(); ++i)
      if (positions_m[i] < 0 || angles_deg[i] < 0) return *why = "thresholds must be >= 0", false;
    why->clear();
    ParseLabelled(groups, "groups", why);
    ParseLabelled(splits, "splits", why);
    return why->empty();
  }
};

using Labels = std::vector<std::pair<std::string, std::regex>>;
using Buckets = std::map<std::pair<std::string, std::string>, std::vector<QueryError>>;  // (group, split) -> errors

// Each query image with a ground-truth pose: its error (and how many had none).
std::vector<QueryError> QueryErrors(kp::Kapture& gt, kp::Kapture& est, const Labels& groups, const Labels& splits,
                                    int* without_gt) {
  std::vector<QueryError> errors;
  for (const auto& r : gt.ReadDataRecords(kp::kSensorCamera)) {
    const auto truth = gt.DevicePose(r.timestamp, r.device_id);
    if (!truth) {
      ++*without_gt;
      continue;
    }
    QueryError e = ComputeError(*truth, est.DevicePose(r.timestamp, r.device_id));
    e.image = r.path;
    e.device = r.device_id;
    e.group = LabelOf(groups, r.device_id);
    e.split = LabelOf(splits, r.path);
    errors.push_back(e);
  }
  return errors;
}

// Buckets: all, each group, each split, each group x split.
Buckets BucketsOf(const std::vector<QueryError>& errors, bool by_group, bool by_split) {
  Buckets buckets;
  for (const auto& e : errors) {
    buckets[{"all", "all"}].push_back(e);
    if (by_group) buckets[{e.group, "all"}].push_back(e);
    if (by_split) buckets[{"all", e.split}].push_back(e);
    if (by_group && by_split) buckets[{e.group, e.split}].push_back(e);
  }
  return buckets;
}

// One row per bucket: queries, localized, recall at each threshold, medians.
Table SummaryTable(const Buckets& buckets, const EvalOptions& o) {
  Table summary;
  summary.header = {"method", "group", "split", "queries", "localized"};
  for (size_t i = 0; i < o.positions_m.size(); ++i)
    summary.header.push_back(FormatDouble(o.positions_m[i]) + "m," + FormatDouble(o.angles_deg[i]) + "deg");
  summary.header.push_back("median_position_m");
  summary.header.push_back("median_rotation_deg");
  for (const auto& [key, list] : buckets) {
    size_t localized = 0;
    for (const auto& e : list) localized += e.localized;
    std::vector<std::string> row = {o.method, key.first, key.second, std::to_string(list.size()),
                                    std::to_string(localized)};
    for (size_t i = 0; i < o.positions_m.size(); ++i)
      row.push_back(Percent(Recall(list, {o.positions_m[i], o.angles_deg[i]})));
    row.push_back(FormatDouble(MedianPosition(list)));
    row.push_back(FormatDouble(MedianRotation(list)));
    summary.rows.push_back(row);
  }
  return summary;
}

Table PerQueryTable(const std::vector<QueryError>& errors) {
  Table per_query;
  per_query.header = {"image", "device_id", "group", "split", "localized", "position_error_m", "rotation_error_deg"};
  for (const auto& e : errors)
    per_query.rows.push_back({e.image, e.device, e.group, e.split, e.localized ? "1" : "0",
                              e.localized ? FormatDouble(e.position_m) : "",
                              e.localized ? FormatDouble(e.rotation_deg) : ""});
  return per_query;
}

// Figure 7: one curve per bucket in the table (eval/table reads all/all);
// `shown`: all queries, each group and each split (not every group x split:
// that many curves would repeat colours).
Table RecallCurves(const Buckets& buckets, const EvalOptions& o, std::vector<plot::Series>* shown) {
  Table curve_table;
  curve_table.header = {"group", "split", "position_m", "angle_deg", "recall_percent"};
  for (const auto& [key, list] : buckets) {
    // "method", "industrial" (a group, all splits), "test" (a split), "industrial/test".
    const std::string label = key.first == "all" && key.second == "all" ? o.method
                              : key.second == "all"                      ? key.first
                              : key.first == "all"                       ? key.second
                                                                         : key.first + "/" + key.second;
    const plot::Series curve = RecallCurve(list, label, o.curve_max_m, kAnglePerMetre, 150, kRecallDecades);
    if (key.first == "all" || key.second == "all") shown->push_back(curve);
    for (size_t i = 0; i < curve.x.size(); ++i)
      curve_table.rows.push_back({key.first, key.second, FormatDouble(curve.x[i]),
                                  FormatDouble(kAnglePerMetre * curve.x[i]), FormatDouble(curve.y[i])});
  }
  return curve_table;
}

class LocalizationEval : public Stage<EvalOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"eval",
            "localization",
            "Per-query position/rotation errors vs ground truth, recall at thresholds (<=, "
            "unlocalized = failure) by camera group and split, recall curve, tables",
            {{"estimates", "kapture.trajectories", "estimated query poses"},
             {"ground_truth", "kapture.dataset", "query kapture with GT trajectories"}},
            {{"report", "report", "summary.{md,csv,tex}, per_query.csv, curve.{csv,svg,png}"}}};
    meta.version = "1.2.0";
    return meta;
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const auto& o = options();
    const auto groups = ParseLabelled(o.groups, "groups", nullptr);
    const auto splits = ParseLabelled(o.splits, "splits", nullptr);
    kp::Kapture gt(ctx.Input("ground_truth"));
    kp::Kapture est(ctx.Input("estimates"));
    int without_gt = 0;
    const std::vector<QueryError> errors = QueryErrors(gt, est, groups, splits, &without_gt);
    if (errors.empty())
      throw InputError(ctx.Input("ground_truth").string(), 0, "trajectories",
                       "no query image has a ground-truth pose");
    if (without_gt) ctx.Warn(std::to_string(without_gt) + " query images without GT pose skipped");
    const Buckets buckets = BucketsOf(errors, !groups.empty(), !splits.empty());
    const Table summary = SummaryTable(buckets, o);
    std::vector<plot::Series> shown;
    const Table curve_table = RecallCurves(buckets, o, &shown);
    const fs::path out = ctx.output_dir();
    WriteFileAtomic(out / "summary.md", "# " + o.method + "\n\n" + ToMarkdown(summary));
    WriteFileAtomic(out / "summary.csv", ToCsv(summary));
    WriteFileAtomic(out / "summary.tex", ToLatex(summary));
    WriteFileAtomic(out / "per_query.csv", ToCsv(PerQueryTable(errors)));
    WriteFileAtomic(out / "curve.csv", ToCsv(curve_table));
    const plot::Figure figure = RecallFigure(shown, o.method, o.curve_max_m, kAnglePerMetre);
    plot::WriteFigure(figure, (out / "curve.svg").string());
    plot::WriteFigure(figure, (out / "curve.png").string());
    ctx.Info(ToMarkdown(summary));
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(LocalizationEval)

}  // namespace locforge::eval

// eval/localization (one method's errors, recalls, curve) and eval/table
// (several reports combined into one table like the paper's Table 3).
#include <map>
#include <regex>
#include <sstream>

#include "evaluation.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::evaluation {
namespace {

namespace kp = locforge::kapture;

// Figure 7 of the paper: angle threshold (deg) = 10 x position threshold (m).
constexpr double kAnglePerMetre = 10;

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

class LocalizationEval : public Stage<EvalOptions> {
 public:
  static StageMeta Meta() {
    return {"eval",
            "localization",
            "Per-query position/rotation errors vs ground truth, recall at thresholds (<=, "
            "unlocalized = failure) by camera group and split, recall curve, tables",
            {{"estimates", "kapture.trajectories", "estimated query poses"},
             {"ground_truth", "kapture.dataset", "query kapture with GT trajectories"}},
            {{"report", "report", "summary.{md,csv,tex}, per_query.csv, curve.{csv,svg,png}"}}};
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const auto& o = options();
    const auto groups = ParseLabelled(o.groups, "groups", nullptr);
    const auto splits = ParseLabelled(o.splits, "splits", nullptr);
    kp::Kapture gt(ctx.Input("ground_truth"));
    kp::Kapture est(ctx.Input("estimates"));
    std::vector<QueryError> errors;
    int without_gt = 0;
    for (const auto& r : gt.ReadDataRecords(kp::kSensorCamera)) {
      const auto truth = gt.DevicePose(r.timestamp, r.device_id);
      if (!truth) {
        ++without_gt;
        continue;
      }
      QueryError e = ComputeError(*truth, est.DevicePose(r.timestamp, r.device_id));
      e.image = r.path;
      e.device = r.device_id;
      e.group = LabelOf(groups, r.device_id);
      e.split = LabelOf(splits, r.path);
      errors.push_back(e);
    }
    if (errors.empty())
      throw InputError(ctx.Input("ground_truth").string(), 0, "trajectories",
                       "no query image has a ground-truth pose");
    if (without_gt) ctx.Warn(std::to_string(without_gt) + " query images without GT pose skipped");

    // Buckets: all, each group, each split, each group x split.
    std::map<std::pair<std::string, std::string>, std::vector<QueryError>> buckets;
    for (const auto& e : errors) {
      buckets[{"all", "all"}].push_back(e);
      if (!groups.empty()) buckets[{e.group, "all"}].push_back(e);
      if (!splits.empty()) buckets[{"all", e.split}].push_back(e);
      if (!groups.empty() && !splits.empty()) buckets[{e.group, e.split}].push_back(e);
    }
    Table summary;
    summary.header = {"method", "group", "split", "queries", "localized"};
    for (size_t i = 0; i < o.positions_m.size(); ++i)
      summary.header.push_back(FormatDouble(o.positions_m[i]) + "m," +
                               FormatDouble(o.angles_deg[i]) + "deg");
    summary.header.push_back("median_position_m");
    summary.header.push_back("median_rotation_deg");
    for (const auto& [key, list] : buckets) {
      size_t localized = 0;
      for (const auto& e : list) localized += e.localized;
      std::vector<std::string> row = {o.method, key.first, key.second,
                                      std::to_string(list.size()), std::to_string(localized)};
      for (size_t i = 0; i < o.positions_m.size(); ++i)
        row.push_back(Percent(Recall(list, {o.positions_m[i], o.angles_deg[i]})));
      row.push_back(FormatDouble(MedianPosition(list)));
      row.push_back(FormatDouble(MedianRotation(list)));
      summary.rows.push_back(row);
    }
    Table per_query;
    per_query.header = {"image", "device_id", "group", "split", "localized", "position_error_m",
                        "rotation_error_deg"};
    for (const auto& e : errors)
      per_query.rows.push_back({e.image, e.device, e.group, e.split, e.localized ? "1" : "0",
                                e.localized ? FormatDouble(e.position_m) : "",
                                e.localized ? FormatDouble(e.rotation_deg) : ""});
    // Figure 7: one curve per bucket in curve.csv (eval/table reads all/all);
    // the figure shows all queries, each group and each split (not every
    // group x split: that many curves would repeat colours).
    std::vector<plot::Series> curves, shown;
    Table curve_table;
    curve_table.header = {"group", "split", "position_m", "angle_deg", "recall_percent"};
    for (const auto& [key, list] : buckets) {
      // "method", "industrial" (a group, all splits), "test" (a split), "industrial/test".
      const std::string label = key.first == "all" && key.second == "all" ? o.method
                                : key.second == "all"                      ? key.first
                                : key.first == "all"                       ? key.second
                                                                           : key.first + "/" + key.second;
      curves.push_back(RecallCurve(list, label, o.curve_max_m, kAnglePerMetre, 150, kRecallDecades));
      if (key.first == "all" || key.second == "all") shown.push_back(curves.back());
      for (size_t i = 0; i < curves.back().x.size(); ++i)
        curve_table.rows.push_back({key.first, key.second, FormatDouble(curves.back().x[i]),
                                    FormatDouble(kAnglePerMetre * curves.back().x[i]),
                                    FormatDouble(curves.back().y[i])});
    }
    const fs::path out = ctx.output_dir();
    WriteFileAtomic(out / "summary.md", "# " + o.method + "\n\n" + ToMarkdown(summary));
    WriteFileAtomic(out / "summary.csv", ToCsv(summary));
    WriteFileAtomic(out / "summary.tex", ToLatex(summary));
    WriteFileAtomic(out / "per_query.csv", ToCsv(per_query));
    WriteFileAtomic(out / "curve.csv", ToCsv(curve_table));
    const plot::Figure figure = RecallFigure(shown, o.method, o.curve_max_m, kAnglePerMetre);
    plot::WriteFigure(figure, (out / "curve.svg").string());
    plot::WriteFigure(figure, (out / "curve.png").string());
    ctx.Info(ToMarkdown(summary));
  }
};

struct TableOptions {
  std::string title = "Localization recall";  // Heading of table.md.
  static void Declare(ParamSchema<TableOptions>& s) {
    s.Add("title", &TableOptions::title, "heading of table.md");
  }
};

class CombinedTable : public Stage<TableOptions> {
 public:
  static StageMeta Meta() {
    return {"eval",
            "table",
            "Combines eval/localization reports into one table (rows: methods; columns: "
            "group/split recalls as a / b / c), like the paper's Table 3",
            {{"reports", "report", "eval/localization reports", LF_PORT_MULTIPLE}},
            {{"table", "report", "table.{md,csv,tex}; curves.{svg,png}: every method's recall curve"}}};
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    std::vector<std::string> columns;  // "group/split" in first-seen order
    std::map<std::string, std::map<std::string, std::string>> cells;  // method -> column -> cell
    std::vector<std::string> methods;
    for (const fs::path& report : ctx.Inputs("reports")) {
      const fs::path file = report / "summary.csv";
      const Table t = FromCsv(ReadFile(file), file.string());
      if (t.header.size() < 8 || t.header[0] != "method")
        throw InputError(file.string(), 1, "header", "not an eval/localization summary");
      const size_t thresholds = t.header.size() - 7;
      for (const auto& row : t.rows) {
        const std::string column = row[1] + "/" + row[2];
        if (std::find(columns.begin(), columns.end(), column) == columns.end())
          columns.push_back(column);
        if (std::find(methods.begin(), methods.end(), row[0]) == methods.end())
          methods.push_back(row[0]);
        std::string cell;
        for (size_t i = 0; i < thresholds; ++i) cell += (i ? " / " : "") + row[5 + i];
        cells[row[0]][column] = cell;
      }
    }
    // Figure 7 across methods: each report's all/all curve.
    std::vector<plot::Series> curves;
    double max_m = 0;
    for (const fs::path& report : ctx.Inputs("reports")) {
      const fs::path file = report / "curve.csv";
      if (!fs::exists(file)) continue;
      const Table c = FromCsv(ReadFile(file), file.string());
      const Table summary = FromCsv(ReadFile(report / "summary.csv"), "summary.csv");
      plot::Series s;
      s.label = summary.rows.empty() ? report.filename().string() : summary.rows[0][0];
      for (const auto& row : c.rows)
        if (row.size() == 5 && row[0] == "all" && row[1] == "all") {
          s.x.push_back(std::stod(row[2]));
          s.y.push_back(std::stod(row[4]));
        }
      if (s.x.empty()) continue;
      max_m = std::max(max_m, s.x.back());
      curves.push_back(std::move(s));
    }
    Table table;
    table.header = {"method"};
    for (const auto& c : columns) table.header.push_back(c == "all/all" ? "all" : c);
    for (const auto& m : methods) {
      std::vector<std::string> row = {m};
      for (const auto& c : columns) {
        auto it = cells[m].find(c);
        row.push_back(it == cells[m].end() ? "-" : it->second);
      }
      table.rows.push_back(row);
    }
    const fs::path out = ctx.output_dir();
    WriteFileAtomic(out / "table.md", "# " + options().title +
                                          "\n\nRecall (%) at the thresholds of each report "
                                          "(default 0.1 m/1 deg, 0.25 m/2 deg, 1 m/5 deg).\n\n" +
                                          ToMarkdown(table));
    WriteFileAtomic(out / "table.csv", ToCsv(table));
    WriteFileAtomic(out / "table.tex", ToLatex(table));
    if (!curves.empty()) {
      const plot::Figure figure = RecallFigure(curves, options().title, max_m, kAnglePerMetre);
      plot::WriteFigure(figure, (out / "curves.svg").string());
      plot::WriteFigure(figure, (out / "curves.png").string());
    }
    ctx.Info(ToMarkdown(table));
  }
};

}  // namespace
}  // namespace locforge::evaluation

LOCFORGE_PLUGIN("evaluation", "1.2.0", "Localization evaluation and tables",
                locforge::evaluation::LocalizationEval, locforge::evaluation::CombinedTable)

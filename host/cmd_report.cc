// locforge report: one self-contained HTML file of a workspace's last run:
// the summary a person reads first, warnings, the dataset, the ground
// truth's quality (LiDAR half, joins, the refined ground truth, Table 4),
// the benchmark (tables like Table 3, recall curves), the run's timing and
// cache hits, and the graph with every parameter. Figures are the ones the
// stages drew (the SDK's plot library), inlined as data URIs.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <set>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "commands.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "report_html.h"
#include "run_record.h"
#include "workspace.h"

namespace locforge::host {

namespace {

using report::Csv;
using report::Escape;

const char kReportHelp[] = R"(Usage: locforge report WORKSPACE [-o FILE] [--run RECORD]

Writes one self-contained HTML file (figures inlined, no script, no network)
of the workspace's last run: a summary, warnings (failed nodes, sequences
the LiDAR half refused to join, queries that could not be localized, the
stages' warnings), the dataset, the ground truth's quality (ATE/RPE, joins,
the trajectory plot with loop edges, the refined ground truth against the
truth, Table 4), the benchmark (the recall table and curves), per-node timing
with cache hits, and the graph with every parameter. Every table holds the
exact values of the CSV file it names. Prints the report's path.

Options:
  -o FILE       Write the report to FILE (default: WORKSPACE/report.html)
  --run RECORD  Report this run record (default: the newest
                WORKSPACE/logs/run-*.json, written by every locforge run)
)";

const char kCss[] = R"(
:root { --ink: #1a1a1a; --muted: #555; --line: #d0d0d0; --accent: #0072b2; --warn: #d55e00; --bg: #f6f7f9; }
* { box-sizing: border-box; }
body { margin: 0; font: 15px/1.45 "DejaVu Sans", "Segoe UI", Arial, sans-serif; color: var(--ink); background: #fff; }
main { max-width: 1180px; margin: 0 auto; padding: 20px 24px 48px; }
h1 { font-size: 26px; margin: 0 0 4px; }
h2 { font-size: 20px; margin: 34px 0 10px; padding-bottom: 4px; border-bottom: 2px solid var(--accent); }
h3 { font-size: 16px; margin: 22px 0 8px; }
p { margin: 6px 0; }
code { font-size: 13px; background: var(--bg); padding: 1px 4px; border-radius: 3px; word-break: break-all; }
.meta { color: var(--muted); font-size: 13px; }
.cards { display: grid; grid-template-columns: repeat(auto-fit, minmax(205px, 1fr)); gap: 12px; margin: 16px 0; }
.card { border: 1px solid var(--line); border-radius: 8px; padding: 10px 14px; background: var(--bg); }
.card h3 { margin: 0 0 6px; font-size: 13px; text-transform: uppercase; letter-spacing: .04em; color: var(--muted); }
.card .big { font-size: 24px; font-weight: bold; }
.card p { font-size: 13px; margin: 2px 0; }
.warnings { border-left: 4px solid var(--warn); background: #fdf1ec; padding: 8px 14px; margin: 12px 0; }
.warnings ul { margin: 4px 0; padding-left: 20px; }
.ok { border-left: 4px solid #009e73; background: #eaf7f2; padding: 8px 14px; margin: 12px 0; }
nav { font-size: 14px; margin: 8px 0 0; }
nav a { margin-right: 14px; color: var(--accent); text-decoration: none; }
.table-wrap { overflow-x: auto; margin: 8px 0 14px; }
table { border-collapse: collapse; font-size: 13px; }
caption { text-align: left; font-weight: bold; padding: 4px 0; }
caption .source { font-weight: normal; color: var(--muted); font-size: 12px; margin-left: 6px; }
th, td { border: 1px solid var(--line); padding: 3px 8px; vertical-align: top; }
th { background: var(--bg); text-align: left; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
tr.ran td:first-child { border-left: 4px solid var(--accent); }
tr.cached td:first-child { border-left: 4px solid #bbb; }
tr.failed td { background: #fdf1ec; }
.bar { height: 10px; background: var(--accent); min-width: 1px; }
figure { margin: 10px 0 18px; }
figure img { max-width: 100%; height: auto; border: 1px solid var(--line); }
figcaption { font-size: 13px; color: var(--muted); }
.figs { display: grid; grid-template-columns: repeat(auto-fit, minmax(420px, 1fr)); gap: 12px; }
.graph { overflow-x: auto; }
.graph img { max-width: 100%; height: auto; }
.params { columns: 2 360px; column-gap: 24px; font-size: 12px; }
.params div { break-inside: avoid; margin: 0 0 10px; }
.params table { font-size: 12px; width: 100%; }
.params td { word-break: break-word; }
pre { background: var(--bg); padding: 8px; font-size: 12px; overflow-x: auto; white-space: pre-wrap; }
@media print {
  body { font-size: 11pt; }
  main { max-width: none; padding: 0; }
  nav { display: none; }
  h2 { break-after: avoid; }
  figure, .card, table { break-inside: avoid; }
  .table-wrap, .graph { overflow: visible; }
  .figs { grid-template-columns: 1fr 1fr; }
  a { color: inherit; text-decoration: none; }
}
)";

struct Node {
  const RunRecord::Node* record;
  fs::path folder;     // the node's artifacts (absolute)
  std::string shown;   // "nodes/<name>" (variants/<v>/nodes/<name> with a matrix)
};

class ReportBuilder {
 public:
  ReportBuilder(const fs::path& workspace, const RunRecord& run) : workspace_(workspace), run_(run) {
    for (const auto& n : run.nodes) {
      if (n.folder.empty()) continue;
      nodes_.push_back({&n, n.folder,
                        (n.variant.empty() ? fs::path("nodes") : fs::path("variants") / n.variant / "nodes") / n.name});
    }
  }

  std::string Build();

 private:
  std::vector<const Node*> OfStage(const std::string& stage) const {
    std::vector<const Node*> out;
    for (const auto& n : nodes_)
      if (n.record->stage == stage) out.push_back(&n);
    return out;
  }
  bool Has(const Node& n, const std::string& file) const {
    std::error_code ec;
    return fs::is_regular_file(n.folder / file, ec);
  }
  std::string Source(const Node& n, const std::string& file) const { return (fs::path(n.shown) / file).string(); }
  std::string Label(const Node& n) const {
    return n.record->variant.empty() ? n.record->name : n.record->variant + " / " + n.record->name;
  }
  // A CSV of a node as a table; "" when absent or unreadable (a warning).
  std::string CsvTable(const Node& n, const std::string& file, const std::string& caption,
                       const std::vector<std::string>& columns = {},
                       report::Unit fallback = report::Unit::kNone);
  std::string Figure(const Node& n, const std::string& file, const std::string& caption);
  void Warn(const std::string& text) { warnings_.push_back(text); }

  std::string Summary();
  std::string Dataset();
  std::string GroundTruth();
  std::string Benchmark();
  std::string Others();
  std::string Timing();
  std::string Graph();
  void CollectLogWarnings();

  fs::path workspace_;
  const RunRecord& run_;
  std::vector<Node> nodes_;
  std::vector<std::string> warnings_;
  std::set<const Node*> shown_;  // nodes a section already presented
};

std::string ReportBuilder::CsvTable(const Node& n, const std::string& file, const std::string& caption,
                                    const std::vector<std::string>& columns, report::Unit fallback) {
  if (!Has(n, file)) return "";
  try {
    return report::Table(report::ReadCsv(n.folder / file), Source(n, file), caption, columns, fallback);
  } catch (const std::exception& e) {
    Warn(std::string("unreadable table: ") + e.what());
    return "";
  }
}

std::string ReportBuilder::Figure(const Node& n, const std::string& file, const std::string& caption) {
  const std::string img = report::Image(n.folder / file, caption);
  if (img.empty()) return "";
  return "<figure>" + img + "<figcaption>" + Escape(caption) + " <code>" + Escape(Source(n, file)) +
         "</code></figcaption></figure>\n";
}

// Reads a JSON/YAML file; a null node when absent or malformed.
YAML::Node LoadJson(const fs::path& file) {
  try {
    std::error_code ec;
    if (fs::is_regular_file(file, ec)) return YAML::LoadFile(file.string());
  } catch (const std::exception&) {
  }
  return YAML::Node();
}

double Number(const std::string& s, double fallback = std::nan("")) {
  if (s.empty()) return fallback;
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  return end && *end == '\0' ? v : fallback;
}

std::string Fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "-";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

std::string Duration(double seconds) {
  if (seconds < 120) return Fixed(seconds, 1) + " s";
  return Fixed(seconds / 60, 1) + " min";
}

// One summary card: a title, a big figure, lines of detail (HTML, escaped by the caller).
void Card(std::string* cards, const std::string& title, const std::string& big, const std::vector<std::string>& lines) {
  *cards += "<div class=\"card\"><h3>" + Escape(title) + "</h3><div class=\"big\">" + big + "</div>";
  for (const auto& l : lines) *cards += "<p>" + l + "</p>";
  *cards += "</div>\n";
}

// The recording (simulated): images, scans, true poses, preset and seed.
void RecordingCard(const Node& n, std::string* cards) {
  try {
    const auto s = kapture::InspectKapture(n.folder);
    int64_t images = 0, scans = 0;
    for (const auto& r : s.records) {
      if (r.sensor_type == "camera") images = r.count;
      if (r.sensor_type == "lidar") scans = r.count;
    }
    std::vector<std::string> lines = {
        Escape(std::to_string(scans) + " LiDAR scans, " + std::to_string(s.trajectory_poses) + " true poses")};
    const auto p = n.record->params;
    for (const auto& [k, v] : p)
      if (k == "preset" || k == "seed") lines.push_back(Escape(k + ": " + v));
    Card(cards, "Recording (simulated)", Escape(std::to_string(images)) + " images", lines);
  } catch (const std::exception&) {
  }
}

// The LiDAR half against the truth (eval/joins): false when its summary is unreadable.
bool JoinsCard(const Node& n, std::string* cards) {
  const YAML::Node j = LoadJson(n.folder / "summary.json");
  if (!j || !j.IsMap()) return false;
  auto num = [&](const char* k) { return j[k] ? Number(j[k].Scalar()) : std::nan(""); };
  Card(cards, "LiDAR ground truth", Escape(report::FormatLength(num("ate_whole_m")) + " ATE"),
       {Escape(report::FormatDegrees(num("rotation_whole_deg")) + " rotation RMS, whole recording, one rigid alignment"),
        Escape(Fixed(num("right"), 0) + " sequence(s) joined right, " + Fixed(num("wrong"), 0) + " wrong, " +
               Fixed(num("refused"), 0) + " refused")});
  return true;
}

// An eval/trajectory node's ATE: false when it has none.
bool TrajectoryCard(const Node& n, std::string* cards) {
  const YAML::Node j = LoadJson(n.folder / "metrics.json");
  if (!j || !j["ape_translation_m"]) return false;
  Card(cards, "Trajectory (" + n.record->name + ")",
       Escape(report::FormatLength(Number(j["ape_translation_m"]["rmse"].Scalar())) + " ATE"),
       {Escape(report::FormatDegrees(Number(j["ape_rotation_deg"]["rmse"].Scalar())) + " rotation RMS")});
  return true;
}

// The refined ground truth against the truth: the last row of eval/calibration.
// False when the table has no row (the next node is tried); true otherwise,
// an unreadable table included.
bool CalibrationCard(const Node& n, std::string* cards) {
  try {
    const Csv c = report::ReadCsv(n.folder / "calibration.csv");
    if (c.rows.empty()) return false;
    const size_t last = c.rows.size() - 1;
    Card(cards, "Refined ground truth (" + c.Cell(last, "estimate") + ")",
         Escape(report::FormatLength(Number(c.Cell(last, "position RMS (cm)")) * 1e-2)),
         {Escape("camera positions RMS; rotations " + report::FormatDegrees(Number(c.Cell(last, "rotation RMS (deg)")))),
          Escape("focal error " + report::FormatPercent(Number(c.Cell(last, "focal error RMS (%)"))) + " RMS, from " +
                 report::FormatPercent(Number(c.Cell(0, "focal error RMS (%)"))) + " (" + c.Cell(0, "estimate") + ")")});
  } catch (const std::exception&) {
  }
  return true;
}

// The benchmark: recall of each method at the finest thresholds (rows all/all).
void LocalizationCards(const Node& n, std::string* cards) {
  try {
    const Csv c = report::ReadCsv(n.folder / "summary.csv");
    for (size_t r = 0; r < c.rows.size(); ++r) {
      if (c.Cell(r, "group") != "all" || c.Cell(r, "split") != "all") continue;
      std::vector<std::string> lines;
      std::string big;
      for (size_t col = 0; col < c.header.size(); ++col) {
        const std::string& h = c.header[col];
        // Recall columns: "0.1m,1deg" (eval/localization), also "(0.1m, 1deg)".
        const bool recall = h.find("m,") != std::string::npos && h.size() > 3 && h.compare(h.size() - 3, 3, "deg") == 0;
        if (!recall) continue;
        const std::string value = report::DisplayCell(c.rows[r][col], report::Unit::kRecall);
        if (big.empty()) big = Escape(value);
        lines.push_back(Escape(h + ": " + value));
      }
      if (!c.Cell(r, "queries").empty()) lines.push_back(Escape(c.Cell(r, "queries") + " queries"));
      Card(cards, "Localization: " + c.Cell(r, "method"), big.empty() ? "-" : big, lines);
    }
  } catch (const std::exception&) {
  }
}

// The run: nodes computed, cached and failed, threads, end.
void RunCard(const RunRecord& run, std::string* cards) {
  int ran = 0, cached = 0, failed = 0;
  double computed = 0;
  for (const auto& n : run.nodes) {
    if (n.status == "ran" || n.status == "resumed") ++ran, computed += n.seconds;
    if (n.status == "cached") ++cached;
    if (n.status == "failed") ++failed;
  }
  Card(cards, "Run", Duration(run.seconds),
       {Escape(std::to_string(ran) + " nodes computed (" + Duration(computed) + "), " + std::to_string(cached) +
               " cached" + (failed ? ", " + std::to_string(failed) + " failed" : "")),
        Escape(std::to_string(run.threads) + " threads, finished " + run.finished)});
}

std::string ReportBuilder::Summary() {
  std::string cards;
  for (const Node* n : OfStage("source/simulator")) {
    RecordingCard(*n, &cards);
    break;
  }
  for (const Node* n : OfStage("eval/joins"))
    if (JoinsCard(*n, &cards)) break;
  if (OfStage("eval/joins").empty())
    for (const Node* n : OfStage("eval/trajectory"))
      if (TrajectoryCard(*n, &cards)) break;
  for (const Node* n : OfStage("eval/calibration"))
    if (CalibrationCard(*n, &cards)) break;
  for (const Node* n : OfStage("eval/localization")) LocalizationCards(*n, &cards);
  RunCard(run_, &cards);
  return "<section id=\"summary\" class=\"cards\">\n" + cards + "</section>\n";
}

std::string ReportBuilder::Dataset() {
  std::string h;
  for (const auto& n : nodes_) {
    if (n.record->stage.rfind("source/", 0) != 0) continue;
    std::error_code ec;
    if (!fs::is_directory(n.folder / "sensors", ec)) continue;
    shown_.insert(&n);
    h += "<h3>" + Escape(Label(n)) + " <span class=\"meta\">" + Escape(n.record->stage) + "</span></h3>\n";
    try {
      const auto s = kapture::InspectKapture(n.folder);
      std::string sensors;
      for (const auto& [type, count] : s.sensors_by_type)
        sensors += (sensors.empty() ? "" : ", ") + std::to_string(count) + " " + type;
      h += "<p>Sensors: " + Escape(sensors) + "; rigs: " + std::to_string(s.rigs) + "; poses: " +
           std::to_string(s.trajectory_poses) + " of " + std::to_string(s.trajectory_devices) + " devices.</p>\n";
      h += "<div class=\"table-wrap\"><table><thead><tr><th>records</th><th>count</th><th>devices</th>"
           "<th>duration</th><th>missing files</th></tr></thead><tbody>";
      for (const auto& r : s.records)
        h += "<tr><td>" + Escape(r.sensor_type) + "</td><td class=\"num\">" + std::to_string(r.count) +
             "</td><td class=\"num\">" + std::to_string(r.devices) + "</td><td class=\"num\">" +
             report::FormatDuration((r.last - r.first) * 1e-6) + "</td><td class=\"num\">" + std::to_string(r.missing_files) +
             "</td></tr>";
      h += "</tbody></table></div>\n";
      for (const auto& p : s.problems) Warn(Label(n) + ": " + p);
    } catch (const std::exception& e) {
      Warn(Label(n) + ": " + e.what());
    }
    if (Has(n, "truth/sequences.txt")) h += CsvTable(n, "truth/sequences.txt", "Sequences (the simulator's truth)");
  }
  return h.empty() ? "" : "<section id=\"dataset\"><h2>Dataset</h2>\n" + h + "</section>\n";
}

std::string ReportBuilder::GroundTruth() {
  std::string h;
  for (const Node* n : OfStage("slam/pose_graph")) {
    shown_.insert(n);
    h += "<h3>LiDAR half: " + Escape(Label(*n)) + "</h3>\n";
    h += Figure(*n, "trajectories.svg", "Top-down trajectories with loop-closure edges");
    h += CsvTable(*n, "joins.csv", "Where every sequence ended up");
    try {
      const Csv joins = report::ReadCsv(n->folder / "joins.csv");
      for (size_t r = 0; r < joins.rows.size(); ++r)
        if (joins.Cell(r, "status") == "separate")
          Warn("the LiDAR half refused to join sequence " + joins.Cell(r, "sequence") + " (" + Source(*n, "joins.csv") +
               ")");
      // Attempts are the comment lines after the "# round,a,b,result,..." header
      // (the comments before it describe the columns, commas included).
      bool attempts = false;
      for (const auto& c : joins.comments) {
        if (c.rfind("# round,", 0) == 0) {
          attempts = true;
          continue;
        }
        if (!attempts || c.rfind("# ", 0) != 0 || c.find(',') == std::string::npos) continue;
        std::istringstream fields(c.substr(2));
        std::string round, a, b, result;
        std::getline(fields, round, ','), std::getline(fields, a, ','), std::getline(fields, b, ','),
            std::getline(fields, result, ',');
        if (!result.empty() && result != "joined")
          Warn("join attempt of " + b + " to " + a + " (round " + round + "): " + result + " (" +
               Source(*n, "joins.csv") + ")");
      }
    } catch (const std::exception&) {
    }
  }
  for (const Node* n : OfStage("eval/joins")) {
    shown_.insert(n);
    h += "<h3>Joins against the truth: " + Escape(Label(*n)) + "</h3>\n";
    h += CsvTable(*n, "joins_eval.csv", "Per sequence: join, ATE, RPE over 1 m, scale");
    try {
      const Csv c = report::ReadCsv(n->folder / "joins_eval.csv");
      for (size_t r = 0; r < c.rows.size(); ++r)
        if (c.Cell(r, "verdict") == "wrong")
          Warn("sequence " + c.Cell(r, "sequence") + " joined wrong (" + Source(*n, "joins_eval.csv") + ")");
    } catch (const std::exception&) {
    }
  }
  for (const Node* n : OfStage("eval/trajectory")) {
    shown_.insert(n);
    h += "<h3>ATE and RPE: " + Escape(Label(*n)) + "</h3>\n";
    h += CsvTable(*n, "metrics.csv", "Absolute (ape) and relative (rpe) pose errors",
                  {"metric", "count", "rmse", "mean", "median", "max"});
  }
  for (const Node* n : OfStage("gt/spline_ba")) {
    shown_.insert(n);
    h += "<h3>SfM half: " + Escape(Label(*n)) + "</h3>\n";
    h += CsvTable(*n, "table4.csv", "Table 4: the reconstruction of the ground truth");
    h += CsvTable(*n, "rounds.csv", "Outer loop: triangulation and spline bundle adjustment rounds");
  }
  for (const Node* n : OfStage("eval/calibration")) {
    shown_.insert(n);
    h += "<h3>Ground truth against the truth: " + Escape(Label(*n)) + "</h3>\n";
    h += CsvTable(*n, "calibration.csv", "Camera poses and calibration, start and refined");
  }
  return h.empty() ? "" : "<section id=\"gt\"><h2>Ground truth quality</h2>\n" + h + "</section>\n";
}

std::string ReportBuilder::Benchmark() {
  std::string h;
  for (const Node* n : OfStage("eval/table")) {
    shown_.insert(n);
    h += CsvTable(*n, "table.csv", "Localization recall (%) at (position, rotation) thresholds, like the paper's Table 3",
                  {}, report::Unit::kRecall);
    h += Figure(*n, "curves.svg", "Recall against the position error threshold");
  }
  std::string curves;
  for (const Node* n : OfStage("eval/localization")) {
    shown_.insert(n);
    h += CsvTable(*n, "summary.csv", "Recall: " + n->record->name);
    curves += Figure(*n, "curve.svg", "Recall curves: " + n->record->name);
  }
  if (!curves.empty()) h += "<div class=\"figs\">" + curves + "</div>\n";
  for (const std::string stage : {"localizer/pnp", "localizer/colmap_registrator"})
    for (const Node* n : OfStage(stage)) {
      if (!Has(*n, "failures.txt")) continue;
      std::ifstream in(n->folder / "failures.txt");
      std::string line;
      int count = 0;
      std::string listed;
      while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#') continue;
        if (++count <= 10) listed += (listed.empty() ? "" : "; ") + line;
      }
      if (count > 0)
        Warn(std::to_string(count) + " queries not localized by " + n->record->name + " (" +
             Source(*n, "failures.txt") + "): " + listed + (count > 10 ? "; ..." : ""));
    }
  return h.empty() ? "" : "<section id=\"benchmark\"><h2>Benchmark</h2>\n" + h + "</section>\n";
}

// Reports of nodes no section shows (e.g. analyses): their Markdown as text.
std::string ReportBuilder::Others() {
  std::string h;
  for (const auto& n : nodes_) {
    if (shown_.count(&n)) continue;
    for (const char* file : {"report.md", "summary.md", "analysis.md"}) {
      if (!Has(n, file)) continue;
      h += "<h3>" + Escape(Label(n)) + " <span class=\"meta\">" + Escape(n.record->stage) + ", <code>" +
           Escape(Source(n, file)) + "</code></span></h3>\n<pre>" + Escape(report::ShortenNumbers(ReadFile(n.folder / file))) +
           "</pre>\n";
      for (const auto& entry : fs::directory_iterator(n.folder))
        if (entry.path().extension() == ".svg")
          h += Figure(n, entry.path().filename().string(), entry.path().stem().string());
      break;
    }
  }
  return h.empty() ? "" : "<section id=\"other\"><h2>Other results</h2>\n" + h + "</section>\n";
}

std::string ReportBuilder::Timing() {
  double longest = 0, computed = 0;
  for (const auto& n : run_.nodes) longest = std::max(longest, n.seconds);
  std::string h =
      "<section id=\"timing\"><h2>Timing and cache</h2>\n<p>Wall-clock of each node in this run "
      "(<code>ran</code>: computed now; <code>cached</code>: its result was already in the workspace, "
      "time to check it). Whole run: " +
      Duration(run_.seconds) + " on " + std::to_string(run_.threads) + " threads.</p>\n"
      "<div class=\"table-wrap\"><table class=\"timing\"><thead><tr><th>node</th><th>stage</th><th>version</th>"
      "<th>status</th><th>items</th><th>seconds</th><th style=\"min-width:160px\"></th></tr></thead><tbody>";
  for (const auto& n : run_.nodes) {
    if (n.status == "ran" || n.status == "resumed") computed += n.seconds;
    const double pct = longest > 0 ? 100.0 * n.seconds / longest : 0;
    h += "<tr class=\"" + Escape(n.status) + "\"><td>" + Escape(n.variant.empty() ? n.name : n.variant + " / " + n.name) +
         "</td><td>" + Escape(n.stage) + "</td><td>" + Escape(n.version) + "</td><td>" + Escape(n.status) +
         "</td><td class=\"num\">" + (n.items ? std::to_string(n.items) : "-") + "</td><td class=\"num\">" +
         Fixed(n.seconds, 2) + "</td><td><div class=\"bar\" style=\"width:" + Fixed(pct, 1) + "%\"></div></td></tr>";
  }
  h += "<tr><td colspan=\"5\"><b>computed in this run</b></td><td class=\"num\"><b>" + Fixed(computed, 2) +
       "</b></td><td></td></tr>";
  h += "</tbody></table></div></section>\n";
  return h;
}

std::string ReportBuilder::Graph() {
  std::string h = "<section id=\"graph\"><h2>Graph and parameters</h2>\n<p>Graph <code>" + Escape(run_.graph) +
                  "</code>" + (run_.description.empty() ? "" : ": " + Escape(run_.description)) +
                  ".<br>Command: <code>" + Escape(run_.command) + "</code></p>\n";
  std::vector<RunRecord::Node> first_variant;
  for (const auto& n : run_.nodes)
    if (n.variant == run_.nodes.front().variant) first_variant.push_back(n);
  h += "<figure class=\"graph\"><img src=\"data:image/svg+xml;base64," + report::Base64(report::GraphSvg(first_variant)) +
       "\" alt=\"the graph\"><figcaption>Nodes by depth, wires from inputs to readers; blue: computed in this run, "
       "grey: cached, red: failed.</figcaption></figure>\n<div class=\"params\">\n";
  for (const auto& n : run_.nodes) {
    h += "<div><table><caption>" + Escape(n.variant.empty() ? n.name : n.variant + " / " + n.name) +
         " <span class=\"source\">" + Escape(n.stage + " " + n.version) + "</span></caption>";
    for (const auto& in : n.inputs)
      h += "<tr><td>&larr; " + Escape(in.port) + "</td><td>" + Escape(in.node + (in.out_port.empty() ? "" : "." + in.out_port)) +
           "</td></tr>";
    for (const auto& [k, v] : n.params) h += "<tr><td>" + Escape(k) + "</td><td>" + Escape(v) + "</td></tr>";
    h += "</table></div>\n";
  }
  h += "</div></section>\n";
  return h;
}

// The stages' own warnings, from the run's log (beside the record).
void ReportBuilder::CollectLogWarnings() {
  const fs::path newest = NewestRun(workspace_, ".log");
  if (newest.empty()) return;
  std::ifstream in(newest);
  std::string line;
  int count = 0;
  while (std::getline(in, line)) {
    std::string lower = line;
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
    if (lower.find("warning") == std::string::npos || lower.find("plugin ") != std::string::npos) continue;
    if (++count <= 20) Warn("log: " + line);
  }
  if (count > 20) Warn(std::to_string(count - 20) + " more warnings in " + newest.string());
}

std::string ReportBuilder::Build() {
  if (run_.failed) Warn("the run failed: " + run_.failure);
  for (const auto& n : run_.nodes)
    if (n.status == "failed" || n.status == "skipped")
      Warn("node " + n.name + " (" + n.stage + "): " + n.status);
  const std::string summary = Summary();
  const std::string dataset = Dataset();
  const std::string gt = GroundTruth();
  const std::string bench = Benchmark();
  const std::string others = Others();
  CollectLogWarnings();
  const std::string title = run_.description.empty() ? fs::path(run_.graph).filename().string() : run_.description;
  std::string h = "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n"
                  "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
                  "<title>locforge report: " + Escape(title) + "</title>\n<style>" + kCss + "</style></head>\n<body><main>\n";
  h += "<header><h1>" + Escape(title) + "</h1><p class=\"meta\">locforge " + Escape(run_.locforge_version) +
       " report of <code>" + Escape(fs::path(run_.graph).filename().string()) + "</code>, run finished " +
       Escape(run_.finished) + ", workspace <code>" + Escape(fs::absolute(workspace_).lexically_normal().string()) +
       "</code></p>\n<nav><a href=\"#warnings\">Warnings</a>" + (dataset.empty() ? "" : "<a href=\"#dataset\">Dataset</a>") +
       (gt.empty() ? "" : "<a href=\"#gt\">Ground truth</a>") + (bench.empty() ? "" : "<a href=\"#benchmark\">Benchmark</a>") +
       (others.empty() ? "" : "<a href=\"#other\">Other results</a>") +
       "<a href=\"#timing\">Timing</a><a href=\"#graph\">Graph</a></nav></header>\n";
  h += summary;
  h += "<section id=\"warnings\">";
  if (warnings_.empty()) {
    h += "<div class=\"ok\">No warnings: every node completed, every sequence joined, every query localized.</div>";
  } else {
    h += "<div class=\"warnings\"><b>Warnings (" + std::to_string(warnings_.size()) + ")</b><ul>";
    for (const auto& w : warnings_) h += "<li>" + Escape(report::ShortenNumbers(w)) + "</li>";
    h += "</ul></div>";
  }
  h += "</section>\n" + dataset + gt + bench + others + Timing() + Graph();
  h += "<footer class=\"meta\"><p>Every table names the CSV file it shows (relative to the workspace) and keeps its "
       "exact values (each cell's data-value); on screen, lengths are in mm below 1 cm, in cm below 1 m, else in m, "
       "angles in degrees with 3 significant digits, recall in % with one decimal, other long numbers with 4 "
       "significant digits.</p></footer>\n</main></body></html>\n";
  return h;
}

}  // namespace

int ReportCommand(const Args& args) {
  std::string output, record_file;
  std::vector<std::string> positional;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--help" || a == "-h") {
      std::cout << kReportHelp;
      return 0;
    }
    if ((a == "-o" || a == "--run") && i + 1 < args.size()) {
      (a == "-o" ? output : record_file) = args[++i];
    } else if (!a.empty() && a[0] == '-') {
      std::cerr << "locforge report: unknown option '" << a << "'\nRun 'locforge report --help' for usage.\n";
      return 2;
    } else {
      positional.push_back(a);
    }
  }
  if (positional.size() != 1) {
    std::cerr << "locforge report: expected one WORKSPACE\nRun 'locforge report --help' for usage.\n";
    return 2;
  }
  const fs::path workspace = positional[0];
  std::error_code ec;
  if (!fs::is_directory(workspace / "nodes", ec) && !fs::is_directory(workspace / "variants", ec)) {
    std::cerr << "locforge report: " << workspace.string()
              << " is not a workspace (no nodes/): run a graph into it first (locforge run GRAPH --workspace "
              << workspace.string() << ")\n";
    return 2;
  }
  const fs::path record = record_file.empty() ? NewestRunRecord(workspace) : fs::path(record_file);
  if (record.empty()) {
    std::cerr << "locforge report: no run record in " << (workspace / "logs").string()
              << " (run-*.json, written by locforge run): run the graph again (cached nodes cost nothing)\n";
    return 2;
  }
  try {
    const RunRecord run = ReadRunRecord(record);
    if (run.nodes.empty()) throw InputError(record.string(), 0, "nodes", "the run has no node");
    const std::string html = ReportBuilder(workspace, run).Build();
    const fs::path out = output.empty() ? workspace / "report.html" : fs::path(output);
    WriteFileAtomic(out, html);
    std::cout << "report: " << out.string() << "\n";
  } catch (const std::exception& e) {
    std::cerr << "locforge report: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

}  // namespace locforge::host

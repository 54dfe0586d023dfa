// analysis/crowd_sweep: recall against crowdedness over query sets of one map
// simulated at several crowd densities (configs/benchmark/crowd_sweep.yaml):
// a table per set, a table of all queries binned by their own crowdedness,
// and the plot.
#include <algorithm>

#include "crowd_sweep.h"
#include "locforge/fs.h"
#include "locforge/plugin.h"

namespace locforge::analysis {
namespace {

using evaluation::Table;

struct CrowdSweepOptions {
  std::vector<double> densities;                       // People per 100 m^2 of each content input, in order.
  std::vector<double> positions_m = {0.1, 0.25, 1.0};  // Position thresholds (<=), the paper's.
  std::vector<double> angles_deg = {1.0, 2.0, 5.0};    // Angle thresholds (<=), one per position.
  int plot_threshold = 1;                              // Index of the threshold plotted.
  std::vector<double> bins_percent = {0, 5, 10, 20, 40};  // Bin edges of query crowdedness (%).

  static void Declare(ParamSchema<CrowdSweepOptions>& s) {
    using O = CrowdSweepOptions;
    s.Add("densities", &O::densities, "people per 100 m^2 of each content input, in the inputs' order");
    s.Add("positions_m", &O::positions_m, "position thresholds in metres (<=)");
    s.Add("angles_deg", &O::angles_deg, "angle thresholds in degrees (<=), one per position");
    s.Add("plot_threshold", &O::plot_threshold, "index of the threshold plotted (0-based)").Range(0, 16);
    s.Add("bins_percent", &O::bins_percent, "ascending bin edges of the queries' own crowdedness (%), last bin open");
  }
  bool Check(std::string* why) const {
    if (positions_m.empty() || positions_m.size() != angles_deg.size())
      return *why = "positions_m and angles_deg need the same, non-zero length", false;
    if (plot_threshold >= static_cast<int>(positions_m.size()))
      return *why = "plot_threshold: index beyond positions_m", false;
    for (size_t i = 1; i < bins_percent.size(); ++i)
      if (!(bins_percent[i] > bins_percent[i - 1])) return *why = "bins_percent: edges must ascend", false;
    return true;
  }
};

// "a", "a; b" ("unnamed masks" for a content report of before image_content 1.1.0).
std::string JoinSources(const std::vector<std::string>& sources) {
  std::string joined;
  for (const std::string& source : sources) joined += (joined.empty() ? "" : "; ") + (source.empty() ? "unnamed masks" : source);
  return joined;
}

class CrowdSweepStage : public Stage<CrowdSweepOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"analysis", "crowd_sweep",
                      "Recall against crowdedness over query sets of one map simulated at several crowd densities: "
                      "a row per set, all queries binned by their own crowdedness, and the plot",
                      {{"content", "report", "analysis/image_content of each query set (with person masks)",
                        LF_PORT_MULTIPLE},
                       {"reports", "report",
                        "eval/localization reports, set-major: the K methods of set 1, then of set 2, ...",
                        LF_PORT_MULTIPLE}},
                      {{"sweep", "report", "sweep.{md,csv,tex}, binned.{md,csv}, recall_vs_crowdedness.{svg,png}"}}};
    meta.version = "1.1.0";
    return meta;
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const auto& o = options();
    const std::vector<fs::path> contents = ctx.Inputs("content"), reports = ctx.Inputs("reports");
    if (contents.empty() || reports.size() % contents.size() != 0)
      throw ParamError("analysis/crowd_sweep: " + std::to_string(reports.size()) + " reports for " +
                       std::to_string(contents.size()) + " query sets: give the same methods for every set");
    if (o.densities.size() != contents.size())
      throw ParamError("analysis/crowd_sweep: densities has " + std::to_string(o.densities.size()) +
                       " values for " + std::to_string(contents.size()) + " content inputs");
    const size_t k = reports.size() / contents.size();
    std::vector<SweepSet> sets(contents.size());
    std::vector<std::string> sources;  // of the crowdedness, distinct, in the sets' order
    for (const fs::path& content : contents) {
      const std::string source = ReadCrowdednessSource(content);
      if (std::find(sources.begin(), sources.end(), source) == sources.end()) sources.push_back(source);
    }
    for (size_t s = 0; s < sets.size(); ++s) {
      sets[s].setting = o.densities[s];
      sets[s].content = ReadContentReport(contents[s]);
      for (size_t m = 0; m < k; ++m) sets[s].methods.push_back(ReadMethodReport(reports[s * k + m]));
    }
    CheckSweep(sets);
    std::string threshold_text;
    const std::vector<evaluation::Threshold> thresholds = MakeThresholds(o.positions_m, o.angles_deg, &threshold_text);
    const std::string note = "Recall (%) at (" + threshold_text + "); unlocalized queries count as failures. "
                             "Crowdedness: % of a query's pixels on people, from " +
                             JoinSources(sources) + ".\n\n";
    const fs::path out = ctx.output_dir();
    const Table sweep = SweepTable(sets, thresholds);
    WriteFileAtomic(out / "sweep.md", "# Recall vs crowd density (one map, queries re-simulated)\n\n" + note +
                                          evaluation::ToMarkdown(sweep));
    WriteFileAtomic(out / "sweep.csv", evaluation::ToCsv(sweep));
    WriteFileAtomic(out / "sweep.tex", evaluation::ToLatex(sweep));
    const Table binned = BinnedTable(sets, o.bins_percent, thresholds);
    WriteFileAtomic(out / "binned.md", "# Recall by the query's own crowdedness (all sets pooled)\n\n" + note +
                                           evaluation::ToMarkdown(binned));
    WriteFileAtomic(out / "binned.csv", evaluation::ToCsv(binned));
    const plot::Figure figure = SweepFigure(sets, thresholds[static_cast<size_t>(o.plot_threshold)]);
    plot::WriteFigure(figure, (out / "recall_vs_crowdedness.svg").string());
    plot::WriteFigure(figure, (out / "recall_vs_crowdedness.png").string());
    ctx.Info(evaluation::ToMarkdown(sweep));
    ctx.Info(evaluation::ToMarkdown(binned));
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(CrowdSweepStage)

}  // namespace locforge::analysis

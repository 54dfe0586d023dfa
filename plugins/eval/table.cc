// eval/table: several eval/localization reports combined into one table,
// like the paper's Table 3.
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

struct TableOptions {
  std::string title = "Localization recall";  // Heading of table.md.
  static void Declare(ParamSchema<TableOptions>& s) {
    s.Add("title", &TableOptions::title, "heading of table.md");
  }
};

class CombinedTable : public Stage<TableOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"eval",
            "table",
            "Combines eval/localization reports into one table (rows: methods; columns: "
            "group/split recalls as a / b / c), like the paper's Table 3",
            {{"reports", "report", "eval/localization reports", LF_PORT_MULTIPLE}},
            {{"table", "report", "table.{md,csv,tex}; curves.{svg,png}: every method's recall curve"}}};
    meta.version = "1.2.0";
    return meta;
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
      plot::Series s;
      s.label = ReportMethod(report);
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

LOCFORGE_REGISTER_STAGE(CombinedTable)

}  // namespace locforge::eval

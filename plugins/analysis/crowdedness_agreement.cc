// analysis/crowdedness_agreement: how well a person detector's crowdedness
// (covered %, count) follows the true crowdedness of the simulator's masks,
// over the query sets of a crowd sweep (configs/benchmark/crowd_sweep_detection.yaml):
// per set and pooled, Pearson and Spearman correlations.
#include <cmath>
#include <numeric>
#include <sstream>

#include "detection.h"
#include "evaluation.h"
#include "locforge/fs.h"
#include "locforge/kapture/csv.h"
#include "locforge/plugin.h"

namespace locforge::analysis {
namespace {

using evaluation::Table;

struct CrowdednessAgreementOptions {
  std::vector<double> densities;  // People per 100 m^2 of each detections input, in order (labels).

  static void Declare(ParamSchema<CrowdednessAgreementOptions>& s) {
    s.Add("densities", &CrowdednessAgreementOptions::densities,
          "people per 100 m^2 of each detections input, in the inputs' order (row labels; empty: 1, 2, ...)");
  }
};

struct Sample {
  std::vector<double> truth, covered, count;
};

// persons.csv of analysis/person_detection run with a recording.
Sample ReadSample(const fs::path& folder) {
  const fs::path file = folder / "persons.csv";
  const Table t = evaluation::FromCsv(ReadFile(file), file.string());
  if (t.header != std::vector<std::string>{"image", "person_count", "covered_percent", "true_crowdedness_percent"})
    throw InputError(file.string(), 1, "header", "not an analysis/person_detection persons.csv");
  Sample s;
  for (size_t r = 0; r < t.rows.size(); ++r) {
    const int64_t line = static_cast<int64_t>(r) + 2;
    const auto& row = t.rows[r];
    if (row.size() != 4) throw InputError(file.string(), line, "row", "expected 4 fields");
    if (row[3].empty())
      throw InputError(file.string(), line, "true_crowdedness_percent",
                       "empty: run analysis/person_detection with the simulator recording as its recording input");
    s.count.push_back(kapture::ParseDouble(row[1], file.string(), line, "person_count"));
    s.covered.push_back(kapture::ParseDouble(row[2], file.string(), line, "covered_percent"));
    s.truth.push_back(kapture::ParseDouble(row[3], file.string(), line, "true_crowdedness_percent"));
  }
  return s;
}

std::string Fixed(double v, int digits) {
  if (std::isnan(v)) return "-";
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << v;
  return s.str();
}

double Mean(const std::vector<double>& v) { return v.empty() ? 0 : std::accumulate(v.begin(), v.end(), 0.0) / v.size(); }

std::vector<std::string> Row(const std::string& label, const Sample& s) {
  return {label,
          std::to_string(s.truth.size()),
          Fixed(Mean(s.truth), 2),
          Fixed(Mean(s.covered), 2),
          Fixed(Mean(s.count), 2),
          Fixed(PearsonCorrelation(s.covered, s.truth), 3),
          Fixed(SpearmanCorrelation(s.covered, s.truth), 3),
          Fixed(PearsonCorrelation(s.count, s.truth), 3),
          Fixed(SpearmanCorrelation(s.count, s.truth), 3)};
}

class CrowdednessAgreementStage : public Stage<CrowdednessAgreementOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"analysis", "crowdedness_agreement",
                      "A person detector's crowdedness (covered %, count) against the simulator's true masks over "
                      "the query sets of a crowd sweep: means, Pearson and Spearman correlations per set and pooled",
                      {{"detections", "person.detections",
                        "analysis/person_detection of each query set, run with its simulator recording",
                        LF_PORT_MULTIPLE}},
                      {{"agreement", "report", "agreement.{md,csv}"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const std::vector<fs::path> inputs = ctx.Inputs("detections");
    const auto& densities = options().densities;
    if (!densities.empty() && densities.size() != inputs.size())
      throw ParamError("analysis/crowdedness_agreement: densities has " + std::to_string(densities.size()) +
                       " values for " + std::to_string(inputs.size()) + " detections inputs");
    Table table;
    table.header = {"people / 100 m^2", "images", "true crowdedness (%)", "covered by boxes (%)", "persons per image",
                    "Pearson covered", "Spearman covered", "Pearson count", "Spearman count"};
    Sample pooled;
    for (size_t i = 0; i < inputs.size(); ++i) {
      const Sample s = ReadSample(inputs[i]);
      table.rows.push_back(Row(densities.empty() ? std::to_string(i + 1) : FormatDouble(densities[i]), s));
      for (auto [to, from] : {std::pair{&pooled.truth, &s.truth}, {&pooled.covered, &s.covered}, {&pooled.count, &s.count}})
        to->insert(to->end(), from->begin(), from->end());
    }
    table.rows.push_back(Row("all (pooled)", pooled));
    const std::string md =
        "# Detected vs true crowdedness\n\nPer image: true crowdedness = % of pixels on people in the simulator's "
        "mask; covered = % of the image inside the union of the detector's person boxes; count = its boxes. "
        "Correlations with the true crowdedness over the images of each set and of all sets pooled "
        "(\"-\": a constant sample).\n\n" +
        evaluation::ToMarkdown(table);
    WriteFileAtomic(ctx.output_dir() / "agreement.md", md);
    WriteFileAtomic(ctx.output_dir() / "agreement.csv", evaluation::ToCsv(table));
    ctx.Info(md);
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(CrowdednessAgreementStage)

}  // namespace locforge::analysis

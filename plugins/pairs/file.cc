// pairs/file: a pairs file as a kapture.pairs artifact.
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <unordered_map>

#include "global_features.h"
#include "locforge/kapture/csv.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "pairs_io.h"

namespace locforge::pairs {

using namespace ::locforge::retrieval;  // the library this stage wires

namespace {

namespace k = locforge::kapture;

struct PairsFileOptions {
  std::string path;
  static void Declare(ParamSchema<PairsFileOptions>& s) {
    s.Add("path", &PairsFileOptions::path, "pairs file: 'image1, image2[, score]' per line").Path().Required();
  }
};

class PairsFileStage : public Stage<PairsFileOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"pairs", "file", "Pairs from a kapture-localization pairs file (validated)",
            {},
            {{"pairs", "kapture.pairs", "pairs.txt"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override {
    k::CsvReader reader(options().path);
    std::vector<ScoredPair> pairs;
    k::CsvRow row;
    while (reader.Next(&row)) {
      k::CheckFieldCount(row, options().path, 2, 3, "query_image, map_image, score");
      for (int f = 0; f < 2; ++f)
        if (row.fields[f].empty())
          throw InputError(options().path, row.line, f ? "map_image" : "query_image", "empty");
      const double score =
          row.fields.size() > 2 ? k::ParseDouble(row.fields[2], options().path, row.line, "score") : 1.0;
      pairs.push_back({row.fields[0], row.fields[1], score});
    }
    WritePairs(ctx.output_dir(), pairs);
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(PairsFileStage)

}  // namespace locforge::pairs

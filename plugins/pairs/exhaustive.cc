// pairs/exhaustive: every pair of map images, or every query with every map image.
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

class ExhaustiveStage : public Stage<NoOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"pairs", "exhaustive",
            "Every map image pair (i < j), or every query with every map image",
            {{"map", "kapture.dataset", "map images"},
             {"query", "kapture.dataset", "query images (query-to-map mode)", LF_PORT_OPTIONAL}},
            {{"pairs", "kapture.pairs", "pairs.txt"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override {
    const auto map = CameraImages(ctx.Input("map"));
    std::vector<ScoredPair> pairs;
    if (ctx.HasInput("query")) {
      for (const auto& q : CameraImages(ctx.Input("query")))
        for (const auto& m : map)
          if (q != m) pairs.push_back({q, m, 1.0});
    } else {
      for (size_t i = 0; i < map.size(); ++i)
        for (size_t j = i + 1; j < map.size(); ++j) pairs.push_back({map[i], map[j], 1.0});
    }
    WritePairs(ctx.output_dir(), pairs);
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(ExhaustiveStage)

}  // namespace locforge::pairs

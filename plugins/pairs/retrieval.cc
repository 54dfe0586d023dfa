// pairs/retrieval: the top-k map images of each image by global descriptor.
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

namespace locforge::retrieval {

namespace {

namespace k = locforge::kapture;

struct RetrievalOptions {
  int topk = 20;
  static void Declare(ParamSchema<RetrievalOptions>& s) {
    s.Add("topk", &RetrievalOptions::topk, "map images kept per query, by cosine similarity").Range(1, 100000);
  }
};

class RetrievalStage : public Stage<RetrievalOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"pairs", "retrieval",
            "Top-k image pairs by cosine similarity of global features (map-to-map, or query-to-map)",
            {{"map_features", "kapture.global_features", "global features of the map images"},
             {"query_features", "kapture.global_features",
              "global features of the queries (query-to-map mode); absent: map-to-map, self excluded",
              LF_PORT_OPTIONAL},
             {"map", "kapture.dataset", "map dataset: only its images are retrieved", LF_PORT_OPTIONAL},
             {"query", "kapture.dataset", "query dataset: only its images are queries", LF_PORT_OPTIONAL}},
            {{"pairs", "kapture.pairs", "pairs.txt"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const GlobalFeatures map_gf = GlobalFeatures::Open(ctx.Input("map_features"));
    std::vector<std::string> map_images = map_gf.images;
    if (ctx.HasInput("map")) map_images = Intersect(map_images, CameraImages(ctx.Input("map")));
    const bool map_to_map = !ctx.HasInput("query_features");
    const GlobalFeatures query_gf = map_to_map ? map_gf : GlobalFeatures::Open(ctx.Input("query_features"));
    std::vector<std::string> queries = map_to_map ? map_images : query_gf.images;
    if (ctx.HasInput("query")) queries = Intersect(queries, CameraImages(ctx.Input("query")));
    if (query_gf.info.dsize != map_gf.info.dsize)
      throw InputError(ctx.Input("query_features").string(), 0, "dsize",
                       "query global features have " + std::to_string(query_gf.info.dsize) +
                           " dims, the map's " + std::to_string(map_gf.info.dsize));
    ctx.Info(std::to_string(queries.size()) + " queries against " + std::to_string(map_images.size()) +
             " map images (" + (map_to_map ? "map-to-map" : "query-to-map") + ")");
    const RowMatrix map = map_gf.Read(map_images);
    std::vector<ScoredPair> pairs;
    constexpr size_t kBlock = 256;
    for (size_t start = 0; start < queries.size(); start += kBlock) {
      ctx.ThrowIfCancelled();
      const std::vector<std::string> block(queries.begin() + start,
                                           queries.begin() + std::min(queries.size(), start + kBlock));
      const Eigen::MatrixXf scores = query_gf.Read(block) * map.transpose();
      for (size_t q = 0; q < block.size(); ++q) {
        std::vector<std::pair<float, int>> ranked;
        for (int m = 0; m < static_cast<int>(map_images.size()); ++m)
          if (!(map_to_map && map_images[m] == block[q])) ranked.emplace_back(-scores(q, m), m);
        const size_t keep = std::min<size_t>(options().topk, ranked.size());
        std::partial_sort(ranked.begin(), ranked.begin() + keep, ranked.end());
        for (size_t r = 0; r < keep; ++r)
          pairs.push_back({block[q], map_images[ranked[r].second], -ranked[r].first});
      }
      ctx.Progress(std::min(queries.size(), start + kBlock), queries.size(), "queries");
    }
    WritePairs(ctx.output_dir(), pairs);
  }
};

}  // namespace

LOCFORGE_EXPORT_STAGE(AddRetrieval, RetrievalStage)

}  // namespace locforge::retrieval

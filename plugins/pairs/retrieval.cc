// pairs/retrieval: the top-k map images of each image by global descriptor.
// Per item: an item is a block of consecutive queries (one matrix product of
// the block against every map descriptor), so a floor's 30 000 x 30 000
// ranking shards over processes and machines and resumes from its journal;
// Finalize concatenates the blocks, in order, into pairs.txt.
#include <algorithm>
#include <cstdio>
#include <mutex>
#include <optional>
#include <sstream>

#include "global_features.h"
#include "locforge/kapture/csv.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "pairs_io.h"

namespace locforge::pairs {

using namespace ::locforge::retrieval;  // the library this stage wires

namespace {

namespace k = locforge::kapture;

struct RetrievalOptions {
  int topk = 20;
  int queries_per_item = 256;
  static void Declare(ParamSchema<RetrievalOptions>& s) {
    s.Add("topk", &RetrievalOptions::topk, "map images kept per query, by cosine similarity").Range(1, 100000);
    s.Add("queries_per_item", &RetrievalOptions::queries_per_item,
          "queries ranked together in one item (the unit of sharding and resuming; another value "
          "may change the scores in their last float bits, not the sharding)")
        .Range(1, 1000000);
  }
};

// Who is ranked against whom: read once per process from the inputs' lists.
struct Plan {
  GlobalFeatures map_gf, query_gf;
  std::vector<std::string> map_images, queries;
  bool map_to_map = false;
};

class RetrievalStage : public PerItemStage<RetrievalOptions> {
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
    meta.version = "1.1.0";  // 1.1.0: per item (blocks of queries), shardable; the same pairs.txt as 1.0.0
    return meta;
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override {
    const Plan& plan = Load(ctx);
    ctx.Info(std::to_string(plan.queries.size()) + " queries against " + std::to_string(plan.map_images.size()) +
             " map images (" + (plan.map_to_map ? "map-to-map" : "query-to-map") + ")");
    std::vector<std::string> items;
    for (size_t b = 0; b < BlockCount(plan); ++b) items.push_back(ItemName(b));
    return items;
  }

  void ProcessItem(RunContext& ctx, const std::string& item) override {
    const Plan& plan = Load(ctx);
    const size_t block_index = BlockIndex(item);
    if (block_index >= BlockCount(plan)) throw Error("pairs/retrieval: item '" + item + "' is past the queries");
    const size_t start = block_index * BlockSize();
    const std::vector<std::string> block(plan.queries.begin() + start,
                                         plan.queries.begin() + std::min(plan.queries.size(), start + BlockSize()));
    const Eigen::MatrixXf scores = plan.query_gf.Read(block) * MapDescriptors().transpose();
    std::vector<ScoredPair> pairs;
    for (size_t q = 0; q < block.size(); ++q) {
      std::vector<std::pair<float, int>> ranked;  // (-score, map index): best first, ties by index
      for (int m = 0; m < static_cast<int>(plan.map_images.size()); ++m)
        if (!(plan.map_to_map && plan.map_images[m] == block[q])) ranked.emplace_back(-scores(q, m), m);
      const size_t keep = std::min<size_t>(options().topk, ranked.size());
      std::partial_sort(ranked.begin(), ranked.begin() + keep, ranked.end());
      for (size_t r = 0; r < keep; ++r) pairs.push_back({block[q], plan.map_images[ranked[r].second], -ranked[r].first});
    }
    AtomicFile file(BlockFile(ctx, item), false);
    WritePairLines(file.stream(), pairs);
    file.Commit();
  }

  void Finalize(RunContext& ctx) override {
    const Plan& plan = Load(ctx);
    AtomicFile file(ctx.output_dir() / "pairs.txt", false);
    file.stream() << kPairsHeader;
    for (size_t b = 0; b < BlockCount(plan); ++b) file.stream() << ReadFile(BlockFile(ctx, ItemName(b)));
    file.Commit();
  }

 private:
  size_t BlockSize() const { return static_cast<size_t>(options().queries_per_item); }
  size_t BlockCount(const Plan& plan) const { return (plan.queries.size() + BlockSize() - 1) / BlockSize(); }
  static std::string ItemName(size_t block) {
    char name[32];
    std::snprintf(name, sizeof(name), "queries-%06zu", block);
    return name;
  }
  static size_t BlockIndex(const std::string& item) {
    size_t block = 0, used = 0;
    try {
      if (item.rfind("queries-", 0) == 0) block = std::stoul(item.substr(8), &used);
    } catch (const std::exception&) {
    }
    if (used == 0 || 8 + used != item.size()) throw Error("pairs/retrieval: unknown item '" + item + "'");
    return block;
  }
  static fs::path BlockFile(RunContext& ctx, const std::string& item) {
    return ctx.output_dir() / "blocks" / (item + ".txt");
  }

  const Plan& Load(RunContext& ctx) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (plan_) return *plan_;
    Plan p;
    p.map_gf = GlobalFeatures::Open(ctx.Input("map_features"));
    p.map_images = p.map_gf.images;
    if (ctx.HasInput("map")) p.map_images = Intersect(p.map_images, CameraImages(ctx.Input("map")));
    p.map_to_map = !ctx.HasInput("query_features");
    p.query_gf = p.map_to_map ? p.map_gf : GlobalFeatures::Open(ctx.Input("query_features"));
    p.queries = p.map_to_map ? p.map_images : p.query_gf.images;
    if (ctx.HasInput("query")) p.queries = Intersect(p.queries, CameraImages(ctx.Input("query")));
    if (p.query_gf.info.dsize != p.map_gf.info.dsize)
      throw InputError(ctx.Input("query_features").string(), 0, "dsize",
                       "query global features have " + std::to_string(p.query_gf.info.dsize) +
                           " dims, the map's " + std::to_string(p.map_gf.info.dsize));
    plan_ = std::move(p);
    return *plan_;
  }
  // Every map descriptor, read on the first item of this process (not to list items).
  const RowMatrix& MapDescriptors() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!map_) map_ = plan_->map_gf.Read(plan_->map_images);
    return *map_;
  }

  std::mutex mutex_;
  std::optional<Plan> plan_;
  std::optional<RowMatrix> map_;
};

}  // namespace

LOCFORGE_REGISTER_STAGE(RetrievalStage)

}  // namespace locforge::pairs

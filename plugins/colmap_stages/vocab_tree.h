// pipeline/colmap_vocab_tree (see vocab_tree.cc).
#ifndef LOCFORGE_PLUGINS_COLMAP_STAGES_VOCAB_TREE_H_
#define LOCFORGE_PLUGINS_COLMAP_STAGES_VOCAB_TREE_H_

#include <map>
#include <string>
#include <vector>

#include "locforge/fs.h"
#include "locforge/plugin.h"

namespace locforge::colmap_stages {

struct VocabTreeOptions {
  std::string vocab_tree;         // Supplied tree (.bin); "" = build one on the map.
  int num_visual_words = 4096;    // vocab_tree_builder words when building.
  int num_images = 100;           // VocabTreeMatching.num_images (neighbours per image).
  int max_num_features = 8192;    // SiftExtraction.max_num_features.
  double timeout_s = 0;           // Kill a colmap step after this many seconds (0: never).
  static void Declare(ParamSchema<VocabTreeOptions>& s) {
    s.Add("vocab_tree", &VocabTreeOptions::vocab_tree, "supplied vocabulary tree file; empty = build on the map");
    s.Add("num_visual_words", &VocabTreeOptions::num_visual_words, "vocab_tree_builder --num_visual_words").Min(16);
    s.Add("num_images", &VocabTreeOptions::num_images, "VocabTreeMatching.num_images").Min(1);
    s.Add("max_num_features", &VocabTreeOptions::max_num_features, "SiftExtraction.max_num_features").Min(16);
    s.Add("timeout_s", &VocabTreeOptions::timeout_s, "kill a colmap step after this many seconds (0: never)").Min(0).NoCacheKey();
  }
};

class VocabTreeStage : public Stage<VocabTreeOptions> {
 public:
  static StageMeta Meta() {
    return {"pipeline",
            "colmap_vocab_tree",
            "Classic COLMAP baseline: SIFT feature_extractor, vocab_tree_builder (or a supplied "
            "tree), vocab_tree_matcher, point_triangulator on the map poses, image_registrator",
            {{"map", "kapture.dataset", "map images (records_data) with poses"},
             {"query", "kapture.dataset", "query images (records_data)"}},
            {{"trajectories", "kapture.trajectories", "registered query poses (+ failures.txt)"}},
            LF_STAGE_NONDETERMINISTIC};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;

 private:
  void Run(RunContext& ctx, const std::vector<std::string>& args, const std::string& tag);
  std::vector<std::string> Extract(RunContext& ctx, const fs::path& db, const fs::path& images,
                                   const fs::path& list, const std::string& tag);
  std::map<std::string, double> seconds_;
};

}  // namespace locforge::colmap_stages

#endif  // LOCFORGE_PLUGINS_COLMAP_STAGES_VOCAB_TREE_H_

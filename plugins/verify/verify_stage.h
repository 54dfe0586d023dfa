// The verify/* stages: per matched pair, keep the matches a geometric model
// explains (verify_stage.h holds what they share).
#ifndef LOCFORGE_PLUGINS_VERIFY_VERIFY_STAGE_H_
#define LOCFORGE_PLUGINS_VERIFY_VERIFY_STAGE_H_

#include <map>
#include <mutex>
#include <optional>
#include <set>

#include "locforge/kapture/csv.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "match_io.h"
#include "matching.h"

namespace locforge::matching {

template <typename Options>
class VerifyStage : public PerItemStage<Options> {
 public:
  using PerItemStage<Options>::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override {
    const auto& s = Load(ctx);
    std::vector<std::string> items;
    for (const auto& [a, b] : k::Kapture(s.matches.root).MatchPairs(s.matches.type))
      items.push_back(MakeItem(a, b));
    return items;
  }
  void ProcessItem(RunContext& ctx, const std::string& item) override {
    const auto& s = Load(ctx);
    const auto [a, b] = SplitItem(item);
    const auto matches = k::Kapture(s.matches.root).ReadMatches(s.matches.type, a, b);
    const auto ka = s.features.Of(a).Keypoints(a), kb = s.features.Of(b).Keypoints(b);
    std::vector<Eigen::Vector2d> pa, pb;
    for (const auto& m : matches) {
      const auto i = static_cast<int64_t>(m.index1), j = static_cast<int64_t>(m.index2);
      if (i < 0 || j < 0 || i >= static_cast<int64_t>(ka.size()) || j >= static_cast<int64_t>(kb.size()))
        throw InputError(k::layout::MatchesFile(a, b), 0, "index",
                         "keypoint index out of range");
      pa.push_back(ka[i]);
      pb.push_back(kb[j]);
    }
    const std::vector<int> keep = Keep(a, b, s.geometry.Find(a), s.geometry.Find(b), pa, pb);
    std::vector<k::Match> kept;
    for (int i : keep) kept.push_back(matches[i]);
    if (static_cast<int>(kept.size()) < std::max(1, this->options().min_inliers)) return;
    k::WriteMatches(ctx.output_dir(), s.matches.type, a, b, kept);
  }
  void Finalize(RunContext& ctx) override {
    fs::create_directories(ctx.output_dir() / k::layout::kMatches / Load(ctx).matches.type);
  }

 protected:
  // Indices of the correspondences to keep; ea / eb: the images' cameras and
  // poses (null when neither `images` nor `query` lists the image).
  virtual std::vector<int> Keep(const std::string& a, const std::string& b,
                                const ImageGeometry::Entry* ea, const ImageGeometry::Entry* eb,
                                const std::vector<Eigen::Vector2d>& pa,
                                const std::vector<Eigen::Vector2d>& pb) = 0;

  // The ports every verification stage has: matches + features in, matches
  // out; `images` / `query` give cameras (and poses) of the two sides.
  static StageMeta VerifyMeta(std::string name, std::string doc, std::string images_doc,
                              uint32_t images_flags, std::string query_doc) {
    return {"verify", std::move(name), std::move(doc),
            {{"matches", "kapture.matches", "matches to verify"},
             kFeaturesPort,
             kQueryFeaturesPort,
             {"images", "kapture.dataset", std::move(images_doc), images_flags},
             {"query", "kapture.dataset", std::move(query_doc), LF_PORT_OPTIONAL}},
            {kMatchesOut}};
  }

  struct State {
    Features features;
    MatchesFolder matches;
    ImageGeometry geometry;
  };
  const State& Load(RunContext& ctx) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!state_) {
      State s{Features::Open(ctx), MatchesFolder::Open(ctx.Input("matches")), {}};
      for (const char* port : {"images", "query"})
        for (const auto& p : ctx.Inputs(port)) s.geometry.Add(p);
      state_ = std::move(s);
    }
    return *state_;
  }

 private:
  std::mutex mutex_;
  std::optional<State> state_;
};

}  // namespace locforge::matching

#endif  // LOCFORGE_PLUGINS_VERIFY_VERIFY_STAGE_H_

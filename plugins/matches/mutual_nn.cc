// matches/mutual_nn: nearest-neighbour descriptor matching per image pair
// (../common/matching); each pair's .matches file is written atomically,
// so sharded and interrupted runs resume.
#include <map>
#include <mutex>
#include <optional>
#include <set>

#include "locforge/kapture/csv.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "match_io.h"
#include "matching.h"

namespace locforge::matches {

using namespace ::locforge::matching;  // the library this stage wires

namespace {

struct MutualNnOptions {
  bool cross_check = true;
  double ratio = 1.0;
  double max_distance = 2.0;
  int min_matches = 0;
  double epipolar_band_px = 0;
  static void Declare(ParamSchema<MutualNnOptions>& s) {
    s.Add("cross_check", &MutualNnOptions::cross_check,
          "keep only mutual nearest neighbours (cross validation)");
    s.Add("ratio", &MutualNnOptions::ratio, "Lowe's ratio test threshold (1: off)").Range(0.1, 1);
    s.Add("max_distance", &MutualNnOptions::max_distance,
          "max L2 distance of unit-normalised descriptors (2: off)").Range(0, 2);
    s.Add("min_matches", &MutualNnOptions::min_matches,
          "pairs with fewer matches get no file").Min(0);
    s.Add("epipolar_band_px", &MutualNnOptions::epipolar_band_px,
          "> 0: when both images have a pose and a camera in `images`, candidates only within this Sampson "
          "distance (px) of the poses' epipolar geometry; the ratio test and mutual check among them (0: off)")
        .Min(0);
  }
};

class MutualNnStage : public PerItemStage<MutualNnOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"matches", "mutual_nn",
            "Nearest-neighbour descriptor matching per pair (mutual check, ratio, distance)",
            {kFeaturesPort, kQueryFeaturesPort, {"pairs", "kapture.pairs", "image pairs to match"},
             {"images", "kapture.dataset", "cameras and poses for epipolar_band_px", LF_PORT_OPTIONAL}},
            {kMatchesOut}};
    // 1.1.0: AVX2 scan; 1.2.0: GEMM-shaped AVX2 tiles (scores may differ in the last float bits);
    // 1.3.0: uint8 descriptors by exact integer dot products (VNNI where the processor has it);
    // 1.4.0: epipolar_band_px (off by default: the same matches as 1.3.0)
    meta.version = "1.4.0";
    return meta;
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override {
    if (options().epipolar_band_px > 0 && ctx.Inputs("images").empty())
      throw ParamError("epipolar_band_px needs the `images` input (the cameras and poses of the band)");
    Load(ctx);
    return ReadPairItems(ctx.Input("pairs"));
  }
  void ProcessItem(RunContext& ctx, const std::string& item) override {
    const Features& f = Load(ctx);
    const auto [a, b] = SplitItem(item);
    const FeatureFolder &fa = f.Of(a), &fb = f.Of(b);
    NnOptions nn;
    nn.cross_check = options().cross_check;
    nn.ratio = options().ratio;
    nn.max_distance = options().max_distance;
    const kapture::FeatureArray &da = fa.Descriptors(a), &db = fb.Descriptors(b);
    const std::optional<EpipolarBand> band = Band(a, b, fa, fb);
    const EpipolarBand* in_band = band ? &*band : nullptr;
    std::optional<ByteDescriptors> bytes_a = ByteDescriptorsOf(da), bytes_b = ByteDescriptorsOf(db);
    const auto matches = bytes_a && bytes_b
                             ? MatchDescriptors(*bytes_a, *bytes_b, nn, in_band)
                             : MatchDescriptors(NormalisedDescriptors(da), NormalisedDescriptors(db), nn, in_band);
    if (static_cast<int>(matches.size()) < std::max(1, options().min_matches)) return;
    k::WriteMatches(ctx.output_dir(), f.map.type, a, b, matches);
  }
  void Finalize(RunContext& ctx) override {
    fs::create_directories(ctx.output_dir() / k::layout::kMatches / Load(ctx).map.type);
  }

 private:
  const Features& Load(RunContext& ctx) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!features_) {
      features_ = Features::Open(ctx);
      if (options().epipolar_band_px > 0)  // the poses serve only the band
        for (const auto& p : ctx.Inputs("images")) geometry_.Add(p);
    }
    return *features_;
  }
  // The pair's epipolar band when asked for and both images are posed (after Load).
  std::optional<EpipolarBand> Band(const std::string& a, const std::string& b, const FeatureFolder& fa,
                                   const FeatureFolder& fb) const {
    if (options().epipolar_band_px <= 0) return std::nullopt;
    const ImageGeometry::Entry *ea = geometry_.Find(a), *eb = geometry_.Find(b);
    if (!ea || !eb || !ea->has_camera || !eb->has_camera || !ea->pose || !eb->pose) return std::nullopt;
    return EpipolarBand::Make(fa.Keypoints(a), fb.Keypoints(b), ea->camera, eb->camera, *ea->pose, *eb->pose,
                              options().epipolar_band_px);
  }
  std::mutex mutex_;
  std::optional<Features> features_;
  ImageGeometry geometry_;
};

}  // namespace

LOCFORGE_REGISTER_STAGE(MutualNnStage)

}  // namespace locforge::matches

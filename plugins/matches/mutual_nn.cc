// Stages: matches/mutual_nn, verify/two_view, verify/known_pose_epipolar.
// All are per pair: an item is "image1,image2" (image1 < image2; kapture
// paths cannot hold a comma), and each pair's .matches file is written
// atomically, so sharded and interrupted runs resume.
#include <map>
#include <mutex>
#include <optional>
#include <set>

#include "locforge/kapture/csv.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "matching.h"

namespace locforge::matching {

namespace {

namespace k = locforge::kapture;

std::pair<std::string, std::string> SplitItem(const std::string& item) {
  const size_t comma = item.find(',');
  if (comma == std::string::npos) throw Error("bad item '" + item + "'");
  return {item.substr(0, comma), item.substr(comma + 1)};
}

std::string MakeItem(const std::string& a, const std::string& b) {
  return a < b ? a + "," + b : b + "," + a;
}

// pairs.txt (kapture-localization): "image1, image2[, score]" per line.
std::vector<std::string> ReadPairItems(const fs::path& folder) {
  const fs::path file = folder / "pairs.txt";
  k::CsvReader reader(file, "pairs.txt");
  std::set<std::string> items;
  k::CsvRow row;
  while (reader.Next(&row)) {
    k::CheckFieldCount(row, "pairs.txt", 2, 3, "query_image, map_image, score");
    if (row.fields[0].empty() || row.fields[1].empty())
      throw InputError("pairs.txt", row.line, row.fields[0].empty() ? "query_image" : "map_image", "empty");
    if (row.fields[0] == row.fields[1]) continue;  // an image with itself
    items.insert(MakeItem(row.fields[0], row.fields[1]));
  }
  return {items.begin(), items.end()};
}

// One type of local features in a kapture.local_features artifact.
struct FeatureFolder {
  std::string type;
  fs::path keypoints_dir, descriptors_dir;
  k::FeatureInfo keypoints, descriptors;

  static FeatureFolder Open(const fs::path& artifact) {
    k::Kapture kap(artifact);
    const auto sets = kap.FeatureSets(k::FeatureKind::kKeypoints);
    if (sets.size() != 1)
      throw InputError(artifact.string(), 0, "reconstruction/keypoints",
                       "expected one keypoints type, found " + std::to_string(sets.size()));
    FeatureFolder f;
    f.type = sets.front().type;
    f.keypoints_dir = sets.front().dir;
    f.keypoints = sets.front().info;
    if (kap.HasFeatureType(k::FeatureKind::kDescriptors, f.type)) {
      const auto& d = kap.GetFeatureSet(k::FeatureKind::kDescriptors, f.type);
      f.descriptors_dir = d.dir;
      f.descriptors = d.info;
    }
    if (f.keypoints.dsize < 2)
      throw InputError((f.keypoints_dir / "keypoints.txt").string(), 0, "dsize", "below 2");
    return f;
  }
  bool Has(const std::string& image) const {
    return fs::exists(SafeJoin(keypoints_dir, image + ".kpt", "pairs.txt"));
  }
  std::vector<Eigen::Vector2d> Keypoints(const std::string& image) const {
    const auto a = k::ReadFeatureFile(SafeJoin(keypoints_dir, image + ".kpt", "pairs.txt"),
                                      keypoints.dtype, keypoints.dsize);
    std::vector<Eigen::Vector2d> out(a.rows);
    for (int64_t r = 0; r < a.rows; ++r) out[r] = {a.At(r, 0), a.At(r, 1)};
    return out;
  }
  k::FeatureArray Descriptors(const std::string& image) const {
    if (descriptors_dir.empty())
      throw InputError(keypoints_dir.string(), 0, "descriptors", "no descriptors of type '" + type + "'");
    return k::ReadFeatureFile(SafeJoin(descriptors_dir, image + ".desc", "pairs.txt"),
                              descriptors.dtype, descriptors.dsize);
  }
};

// The map features and optionally the queries' (a second artifact).
struct Features {
  FeatureFolder map;
  std::optional<FeatureFolder> query;

  static Features Open(RunContext& ctx) {
    Features f{FeatureFolder::Open(ctx.Input("features")), std::nullopt};
    if (ctx.HasInput("query_features")) {
      f.query = FeatureFolder::Open(ctx.Input("query_features"));
      if (f.query->type != f.map.type)
        throw InputError(ctx.Input("query_features").string(), 0, "reconstruction/keypoints",
                         "query keypoints type '" + f.query->type + "' differs from the map's '" +
                             f.map.type + "': matches need one type");
    }
    return f;
  }
  const FeatureFolder& Of(const std::string& image) const {
    if (query && query->Has(image)) return *query;
    if (!map.Has(image))
      throw InputError("pairs", 0, "image", "no keypoints of type '" + map.type + "' for '" + image + "'");
    return map;
  }
};

// Cameras and poses of the images of one or two datasets.
struct ImageGeometry {
  struct Entry {
    Camera camera;
    bool has_camera = false;
    std::optional<Pose> pose;
  };
  std::map<std::string, Entry> images;

  void Add(const fs::path& root) {
    k::Kapture kap(root);
    kap.ForEachDataRecord("camera", [&](const k::DataRecord& r) {
      Entry e;
      const k::Sensor* s = kap.sensors().Find(r.device_id);
      if (s && s->camera && s->camera->model != CameraModelId::kUnknown) {
        e.camera = *s->camera;
        e.has_camera = true;
      }
      e.pose = kap.DevicePose(r.timestamp, r.device_id);
      images.emplace(r.path, e);
    });
  }
  const Entry* Find(const std::string& image) const {
    auto it = images.find(image);
    return it == images.end() ? nullptr : &it->second;
  }
};

struct MatchesFolder {
  std::string type;
  fs::path root;
  static MatchesFolder Open(const fs::path& artifact) {
    k::Kapture kap(artifact);
    const auto types = kap.MatchesTypes();
    if (types.size() != 1)
      throw InputError(artifact.string(), 0, "reconstruction/matches",
                       "expected one keypoints type, found " + std::to_string(types.size()));
    return {types.front(), artifact};
  }
};

const PortMeta kFeaturesPort{"features", "kapture.local_features", "local features of the map (or all) images"};
const PortMeta kQueryFeaturesPort{"query_features", "kapture.local_features",
                                  "local features of the query images, when in another artifact",
                                  LF_PORT_OPTIONAL};
const PortMeta kMatchesOut{"matches", "kapture.matches", "matches per image pair"};

}  // namespace

// ------------------------------------------------------------ mutual NN

struct MutualNnOptions {
  bool cross_check = true;
  double ratio = 1.0;
  double max_distance = 2.0;
  int min_matches = 0;
  static void Declare(ParamSchema<MutualNnOptions>& s) {
    s.Add("cross_check", &MutualNnOptions::cross_check,
          "keep only mutual nearest neighbours (cross validation)");
    s.Add("ratio", &MutualNnOptions::ratio, "Lowe's ratio test threshold (1: off)").Range(0.1, 1);
    s.Add("max_distance", &MutualNnOptions::max_distance,
          "max L2 distance of unit-normalised descriptors (2: off)").Range(0, 2);
    s.Add("min_matches", &MutualNnOptions::min_matches,
          "pairs with fewer matches get no file").Min(0);
  }
};

class MutualNnStage : public PerItemStage<MutualNnOptions> {
 public:
  static StageMeta Meta() {
    return {"matches", "mutual_nn",
            "Nearest-neighbour descriptor matching per pair (mutual check, ratio, distance)",
            {kFeaturesPort, kQueryFeaturesPort, {"pairs", "kapture.pairs", "image pairs to match"}},
            {kMatchesOut}};
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override {
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
    const auto matches = MatchDescriptors(NormalisedDescriptors(fa.Descriptors(a)),
                                          NormalisedDescriptors(fb.Descriptors(b)), nn);
    if (static_cast<int>(matches.size()) < std::max(1, options().min_matches)) return;
    k::WriteMatches(ctx.output_dir(), f.map.type, a, b, matches);
  }
  void Finalize(RunContext& ctx) override {
    fs::create_directories(ctx.output_dir() / k::layout::kMatches / Load(ctx).map.type);
  }

 private:
  const Features& Load(RunContext& ctx) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!features_) features_ = Features::Open(ctx);
    return *features_;
  }
  std::mutex mutex_;
  std::optional<Features> features_;
};

// ------------------------------------------------------ shared by verifiers

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

// ------------------------------------------------------------ two-view

struct TwoViewStageOptions {
  double max_error_px = 4.0;      // RANSAC inlier threshold, pixels.
  double confidence = 0.9999;
  int max_iterations = 10000;
  std::string method = "magsac";  // OpenCV USAC_MAGSAC, or "usac" for USAC_DEFAULT.
  std::string geometry = "auto";  // essential when both cameras are known.
  int min_inliers = 15;           // Pairs with fewer inliers get no file.
  static void Declare(ParamSchema<TwoViewStageOptions>& s) {
    s.Add("max_error_px", &TwoViewStageOptions::max_error_px, "RANSAC inlier threshold (pixels)")
        .Range(0.1, 100);
    s.Add("confidence", &TwoViewStageOptions::confidence, "RANSAC confidence").Range(0.5, 0.999999);
    s.Add("max_iterations", &TwoViewStageOptions::max_iterations, "RANSAC iterations cap")
        .Range(10, 1000000);
    s.Add("method", &TwoViewStageOptions::method,
          "OpenCV USAC flavour: magsac (USAC_MAGSAC) or usac (USAC_DEFAULT)")
        .Choices({"magsac", "usac"});
    s.Add("geometry", &TwoViewStageOptions::geometry,
          "auto: essential when both images have intrinsics, else fundamental")
        .Choices({"auto", "essential", "fundamental"});
    s.Add("min_inliers", &TwoViewStageOptions::min_inliers, "pairs with fewer inliers get no file")
        .Min(0);
  }
  TwoViewOptions Ransac() const {
    TwoViewOptions o;
    o.max_error_px = max_error_px;
    o.confidence = confidence;
    o.max_iterations = max_iterations;
    o.method = method;
    return o;
  }
};

class TwoViewStage : public VerifyStage<TwoViewStageOptions> {
 public:
  static StageMeta Meta() {
    return VerifyMeta("two_view",
                      "RANSAC two-view geometry (OpenCV USAC essential/fundamental); keeps inlier matches",
                      "cameras of the map images (for essential matrices)", LF_PORT_OPTIONAL,
                      "cameras of the query images");
  }
  using VerifyStage::VerifyStage;

 protected:
  std::vector<int> Keep(const std::string& a, const std::string& b, const ImageGeometry::Entry* ea,
                        const ImageGeometry::Entry* eb, const std::vector<Eigen::Vector2d>& pa,
                        const std::vector<Eigen::Vector2d>& pb) override {
    const bool known = ea && eb && ea->has_camera && eb->has_camera;
    const std::string& mode = options().geometry;
    if (mode == "essential" && !known)
      throw InputError("images", 0, "camera", "no intrinsics for '" + (ea && ea->has_camera ? b : a) +
                                                  "' (geometry: essential)");
    const bool essential = mode == "essential" || (mode == "auto" && known);
    return VerifyTwoView(pa, pb, essential ? &ea->camera : nullptr, essential ? &eb->camera : nullptr,
                         options().Ransac())
        .inliers;
  }
};

// ------------------------------------------------- known-pose epipolar

struct EpipolarOptions {
  double max_error_px = 4.0;
  int min_inliers = 1;
  bool keep_unknown = true;
  static void Declare(ParamSchema<EpipolarOptions>& s) {
    s.Add("max_error_px", &EpipolarOptions::max_error_px,
          "Sampson distance to the epipolar geometry of the known poses (pixels)").Range(0.01, 1000);
    s.Add("min_inliers", &EpipolarOptions::min_inliers, "pairs with fewer kept matches get no file").Min(0);
    s.Add("keep_unknown", &EpipolarOptions::keep_unknown,
          "pairs lacking a pose or camera keep all matches (else they are dropped)");
  }
};

class KnownPoseEpipolarStage : public VerifyStage<EpipolarOptions> {
 public:
  static StageMeta Meta() {
    return VerifyMeta("known_pose_epipolar",
                      "Keeps matches consistent with the epipolar geometry of the two known poses",
                      "cameras and poses of the map images", 0,
                      "cameras and poses of the query images");
  }
  using VerifyStage::VerifyStage;

 protected:
  std::vector<int> Keep(const std::string&, const std::string&, const ImageGeometry::Entry* ea,
                        const ImageGeometry::Entry* eb, const std::vector<Eigen::Vector2d>& pa,
                        const std::vector<Eigen::Vector2d>& pb) override {
    std::vector<int> keep;
    if (!ea || !eb || !ea->has_camera || !eb->has_camera || !ea->pose || !eb->pose) {
      if (options().keep_unknown)
        for (int i = 0; i < static_cast<int>(pa.size()); ++i) keep.push_back(i);
      return keep;
    }
    const auto errors = EpipolarErrorsPx(pa, pb, ea->camera, eb->camera, *ea->pose, *eb->pose);
    for (int i = 0; i < static_cast<int>(errors.size()); ++i)
      if (errors[i] <= options().max_error_px) keep.push_back(i);
    return keep;
  }
};

}  // namespace locforge::matching

LOCFORGE_PLUGIN("matching", "1.0.0", "Descriptor matching and geometric verification",
                locforge::matching::MutualNnStage, locforge::matching::TwoViewStage,
                locforge::matching::KnownPoseEpipolarStage)

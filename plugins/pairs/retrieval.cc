// Stages: global/densevlad_vocabulary, global/densevlad, global/import,
// pairs/retrieval, pairs/exhaustive, pairs/pose_proximity, pairs/file.
//
// pairs.txt (kapture.pairs) is kapture-localization's list: a
// "# query_image, map_image, score" header then one pair a line. Retrieval
// pairs are ordered by query, then by decreasing score (ties by name).
#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <thread>
#include <unordered_map>

#include "densevlad.h"
#include "locforge/kapture/csv.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::retrieval {

namespace {

namespace k = locforge::kapture;

constexpr const char* kVocabularyFile = "densevlad_vocabulary.bin";

struct ScoredPair {
  std::string query, map;
  double score = 0;
};

void WritePairs(const fs::path& out_dir, const std::vector<ScoredPair>& pairs) {
  AtomicFile file(out_dir / "pairs.txt", false);
  auto& out = file.stream();
  out << "# query_image, map_image, score\n";
  for (const auto& p : pairs) out << p.query << ", " << p.map << ", " << k::FormatDouble(p.score) << "\n";
  file.Commit();
}

std::vector<std::string> CameraImages(const fs::path& dataset) {
  return k::Kapture(dataset).CameraImages();
}

cv::Mat ReadGray(const fs::path& dataset, const std::string& image) {
  const fs::path file =
      k::Kapture(dataset).RecordDataPath(image, k::layout::RecordsFile(k::kSensorCamera));
  cv::Mat gray = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
  if (gray.empty())
    throw InputError(k::layout::RecordsFile("camera"), 0, "image_path",
                     "cannot read image '" + image + "' at " + file.string());
  return gray;
}

// Runs fn(i) for i in [0, n) on `threads` threads; results go by index, so the
// outcome does not depend on the thread count.
template <typename Fn>
void ParallelFor(int64_t n, int threads, Fn fn) {
  std::atomic<int64_t> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto worker = [&] {
    for (int64_t i; (i = next++) < n;) {
      try {
        fn(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        next = n;
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::min<int64_t>(threads, n); ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

// One type of global features in a kapture.global_features artifact.
struct GlobalFeatures {
  std::string type;
  fs::path dir;
  k::FeatureInfo info;
  std::vector<std::string> images;

  static GlobalFeatures Open(const fs::path& artifact) {
    k::Kapture kap(artifact);
    const auto sets = kap.FeatureSets(k::FeatureKind::kGlobalFeatures);
    if (sets.size() != 1)
      throw InputError(artifact.string(), 0, "reconstruction/global_features",
                       "expected one global features type, found " + std::to_string(sets.size()));
    GlobalFeatures g{sets.front().type, sets.front().dir, sets.front().info, {}};
    g.images = kap.FeatureImages(k::FeatureKind::kGlobalFeatures, g.type);
    return g;
  }
  // Rows of unit L2 norm, in the order of `names`.
  RowMatrix Read(const std::vector<std::string>& names) const {
    RowMatrix m(static_cast<int64_t>(names.size()), info.dsize);
    for (size_t i = 0; i < names.size(); ++i) {
      const auto a = k::ReadFeatureFile(SafeJoin(dir, names[i] + ".gfeat"), info.dtype, info.dsize,
                                        type + "/" + names[i] + ".gfeat");
      if (a.rows != 1)
        throw InputError(type + "/" + names[i] + ".gfeat", 0, "", std::to_string(a.rows) + " rows, expected 1");
      for (int64_t c = 0; c < info.dsize; ++c) m(i, c) = static_cast<float>(a.At(0, c));
      const float n = m.row(i).norm();
      if (n > 0) m.row(i) /= n;
    }
    return m;
  }
};

std::vector<std::string> Intersect(const std::vector<std::string>& sorted_a,
                                   const std::vector<std::string>& sorted_b) {
  std::vector<std::string> out;
  std::set_intersection(sorted_a.begin(), sorted_a.end(), sorted_b.begin(), sorted_b.end(),
                        std::back_inserter(out));
  return out;
}

}  // namespace

// ------------------------------------------------------- DenseVLAD vocabulary

struct VocabularyOptions {
  int clusters = 64;
  int sample_size = 100000;
  int iterations = 20;
  int seed = 0;
  int pca_dims = 0;
  int pca_max_images = 2000;
  int max_image_size = 480;
  int grid_step = 4;
  std::vector<double> bin_sizes = {4, 6, 8, 10};
  std::string file;
  static void Declare(ParamSchema<VocabularyOptions>& s) {
    s.Add("clusters", &VocabularyOptions::clusters, "visual words (VLAD has clusters x 128 dims)")
        .Range(2, 4096);
    s.Add("sample_size", &VocabularyOptions::sample_size,
          "dense descriptors sampled over the map images for k-means").Min(100);
    s.Add("iterations", &VocabularyOptions::iterations, "k-means iterations").Range(1, 1000);
    s.Add("seed", &VocabularyOptions::seed, "k-means++ seed").Min(0);
    s.Add("pca_dims", &VocabularyOptions::pca_dims,
          "PCA-whitening dimensions learnt on the map (0: no PCA; at most images - 1)").Min(0);
    s.Add("pca_max_images", &VocabularyOptions::pca_max_images,
          "map images (evenly spaced) used to learn the PCA").Min(2);
    s.Add("max_image_size", &VocabularyOptions::max_image_size,
          "images downscaled so the longer side is at most this (0: never)").Min(0);
    s.Add("grid_step", &VocabularyOptions::grid_step, "pixels between dense SIFT grid points")
        .Range(1, 64);
    s.Add("bin_sizes", &VocabularyOptions::bin_sizes, "SIFT bin widths of the scales (pixels)")
        .Range(1, 64);
    s.Add("file", &VocabularyOptions::file,
          "load this vocabulary file (a densevlad_vocabulary.bin) instead of training; "
          "empty: train (a plain string: its content does not enter the cache key)");
  }
  bool Check(std::string* why) const {
    if (bin_sizes.empty() || bin_sizes.size() >= 16) {
      *why = "parameter 'bin_sizes': give 1 to 15 scales";
      return false;
    }
    if (sample_size < clusters) {
      *why = "parameter 'sample_size': below 'clusters'";
      return false;
    }
    return true;
  }
};

class VocabularyStage : public Stage<VocabularyOptions> {
 public:
  static StageMeta Meta() {
    return {"global", "densevlad_vocabulary",
            "DenseVLAD visual vocabulary (k-means on dense RootSIFT) and PCA-whitening, learnt on the map",
            {{"images", "kapture.dataset", "map images to learn from (unused with 'file')", LF_PORT_OPTIONAL}},
            {{"vocabulary", "densevlad.vocabulary", "densevlad_vocabulary.bin"}}};
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const auto& o = options();
    if (!o.file.empty()) {
      const std::string bytes = ReadFile(o.file);
      (void)Vocabulary::Parse(bytes, o.file);
      WriteFileAtomic(ctx.output_dir() / kVocabularyFile, bytes);
      return;
    }
    if (!ctx.HasInput("images"))
      throw InputError("images", 0, "", "wire map images or give 'file'");
    const fs::path dataset = ctx.Input("images");
    const auto images = CameraImages(dataset);
    if (images.empty()) throw InputError(dataset.string(), 0, "records_camera.txt", "no images");
    Vocabulary v;
    v.dense = {o.max_image_size, o.grid_step, o.bin_sizes};
    // Evenly strided descriptors of every image.
    const int64_t per_image = (o.sample_size + images.size() - 1) / images.size();
    std::vector<RowMatrix> samples(images.size());
    ParallelFor(images.size(), ctx.threads(), [&](int64_t i) {
      ctx.ThrowIfCancelled();
      const RowMatrix d = DenseRootSift(ReadGray(dataset, images[i]), v.dense);
      const int64_t take = std::min<int64_t>(per_image, d.rows());
      samples[i].resize(take, 128);
      for (int64_t j = 0; j < take; ++j) samples[i].row(j) = d.row(j * d.rows() / take);
    });
    int64_t total = 0;
    for (const auto& s : samples) total += s.rows();
    RowMatrix all(total, 128);
    int64_t at = 0;
    for (const auto& s : samples) all.middleRows(at, s.rows()) = s, at += s.rows();
    ctx.Info("k-means: " + std::to_string(total) + " descriptors of " + std::to_string(images.size()) +
             " images into " + std::to_string(o.clusters) + " words");
    v.centres = KMeans(all, o.clusters, o.iterations, static_cast<uint64_t>(o.seed));
    if (o.pca_dims > 0) {
      const int64_t n = std::min<int64_t>(o.pca_max_images, images.size());
      RowMatrix vlads(n, v.centres.size());
      ParallelFor(n, ctx.threads(), [&](int64_t i) {
        ctx.ThrowIfCancelled();
        const auto& image = images[i * images.size() / n];
        vlads.row(i) = Vlad(DenseRootSift(ReadGray(dataset, image), v.dense), v.centres).transpose();
      });
      LearnPcaWhitening(vlads, o.pca_dims, &v);
      ctx.Info("PCA-whitening: " + std::to_string(v.pca_projection.rows()) + " dims from " +
               std::to_string(n) + " images");
    }
    WriteFileAtomic(ctx.output_dir() / kVocabularyFile, v.Serialize());
  }
};

// ------------------------------------------------------- DenseVLAD per image

struct DenseVladOptions {
  std::string type = "densevlad";
  static void Declare(ParamSchema<DenseVladOptions>& s) {
    s.Add("type", &DenseVladOptions::type, "kapture global features type (folder name)");
  }
  bool Check(std::string* why) const {
    if (type.empty() || type.find_first_of("/\\,") != std::string::npos || type == "." || type == "..") {
      *why = "parameter 'type': '" + type + "' is not a folder name";
      return false;
    }
    return true;
  }
};

class DenseVladStage : public PerItemStage<DenseVladOptions> {
 public:
  static StageMeta Meta() {
    return {"global", "densevlad", "DenseVLAD global descriptor per image (float32 .gfeat)",
            {{"images", "kapture.dataset", "images to describe"},
             {"vocabulary", "densevlad.vocabulary", "from global/densevlad_vocabulary"}},
            {{"features", "kapture.global_features", "one .gfeat per image"}}};
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override { return CameraImages(ctx.Input("images")); }
  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const Vocabulary& v = Load(ctx);
    const Eigen::VectorXf d = DenseVladDescriptor(ReadGray(ctx.Input("images"), image), v);
    k::WriteImageFeatures(ctx.output_dir(), options().type, Info(v), image,
                          k::FeatureArray::From(k::DType::kFloat32, d.size(),
                                                std::vector<float>(d.data(), d.data() + d.size())));
  }
  void Finalize(RunContext& ctx) override {
    k::WriteFeatureSetInfo(ctx.output_dir(), options().type, Info(Load(ctx)));
  }

 private:
  static k::FeatureInfo Info(const Vocabulary& v) {
    k::FeatureInfo info;
    info.kind = k::FeatureKind::kGlobalFeatures;
    info.name = "densevlad";
    info.dtype_name = "float32";
    info.dtype = k::DType::kFloat32;
    info.dsize = v.Dimension();
    info.metric_type = "L2";
    return info;
  }
  const Vocabulary& Load(RunContext& ctx) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!vocabulary_) {
      const fs::path file = ctx.Input("vocabulary") / kVocabularyFile;
      vocabulary_ = Vocabulary::Parse(ReadFile(file), file.string());
    }
    return *vocabulary_;
  }
  std::mutex mutex_;
  std::optional<Vocabulary> vocabulary_;
};

// ------------------------------------------------------------ global/import

struct GlobalImportOptions {
  std::string path;
  std::string type;
  static void Declare(ParamSchema<GlobalImportOptions>& s) {
    s.Add("path", &GlobalImportOptions::path,
          "folder holding global_features/ (kapture-localization's global_features/<type>), "
          "or a kapture root with reconstruction/global_features/<type>")
        .Path()
        .Required();
    s.Add("type", &GlobalImportOptions::type, "type to import from a kapture root / name in the output");
  }
};

class GlobalImportStage : public Stage<GlobalImportOptions> {
 public:
  static StageMeta Meta() {
    return {"global", "import", "Imports an existing kapture global features folder (validated copy)",
            {},
            {{"features", "kapture.global_features", "the imported global features"}}};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override {
    const fs::path src = fs::absolute(options().path);
    std::string type = options().type;
    fs::path dir;
    if (fs::exists(src / "global_features" / "global_features.txt")) {
      dir = src / "global_features";
      if (type.empty()) type = src.filename().string();
    } else if (fs::is_directory(src / "reconstruction")) {
      k::Kapture kap(src);
      const auto sets = kap.FeatureSets(k::FeatureKind::kGlobalFeatures);
      if (type.empty()) {
        if (sets.size() != 1)
          throw InputError(src.string(), 0, "type", std::to_string(sets.size()) + " global features types here; set 'type'");
        type = sets.front().type;
      }
      dir = kap.GetFeatureSet(k::FeatureKind::kGlobalFeatures, type).dir;
    } else {
      throw InputError(src.string(), 0, "path",
                       "neither global_features/global_features.txt nor a kapture reconstruction/ here");
    }
    if (type.empty() || type.find_first_of("/\\,") != std::string::npos || type == "." || type == "..")
      throw InputError(src.string(), 0, "type", "'" + type + "' is not a folder name");
    const int64_t n = k::CopyFeatureFolder(
        k::FeatureKind::kGlobalFeatures, dir,
        ctx.output_dir() / k::layout::FeatureRoot(k::FeatureKind::kGlobalFeatures) / type, true);
    ctx.Info("imported " + std::to_string(n) + " global feature files of type '" + type + "'");
  }
};

// ---------------------------------------------------------- pairs/retrieval

struct RetrievalOptions {
  int topk = 20;
  static void Declare(ParamSchema<RetrievalOptions>& s) {
    s.Add("topk", &RetrievalOptions::topk, "map images kept per query, by cosine similarity").Range(1, 100000);
  }
};

class RetrievalStage : public Stage<RetrievalOptions> {
 public:
  static StageMeta Meta() {
    return {"pairs", "retrieval",
            "Top-k image pairs by cosine similarity of global features (map-to-map, or query-to-map)",
            {{"map_features", "kapture.global_features", "global features of the map images"},
             {"query_features", "kapture.global_features",
              "global features of the queries (query-to-map mode); absent: map-to-map, self excluded",
              LF_PORT_OPTIONAL},
             {"map", "kapture.dataset", "map dataset: only its images are retrieved", LF_PORT_OPTIONAL},
             {"query", "kapture.dataset", "query dataset: only its images are queries", LF_PORT_OPTIONAL}},
            {{"pairs", "kapture.pairs", "pairs.txt"}}};
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

// --------------------------------------------------------- pairs/exhaustive

class ExhaustiveStage : public Stage<NoOptions> {
 public:
  static StageMeta Meta() {
    return {"pairs", "exhaustive",
            "Every map image pair (i < j), or every query with every map image",
            {{"map", "kapture.dataset", "map images"},
             {"query", "kapture.dataset", "query images (query-to-map mode)", LF_PORT_OPTIONAL}},
            {{"pairs", "kapture.pairs", "pairs.txt"}}};
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

// ------------------------------------------------------ pairs/pose_proximity

struct ProximityOptions {
  double max_distance = 5.0;
  double max_angle_deg = 60.0;
  int topk = 0;
  int topk_revisit = 0;
  double revisit_min_dt_s = 10.0;
  double seconds_per_unit = 1e-6;
  static void Declare(ParamSchema<ProximityOptions>& s) {
    s.Add("max_distance", &ProximityOptions::max_distance, "max distance of camera centres (m)")
        .Min(0);
    s.Add("max_angle_deg", &ProximityOptions::max_angle_deg,
          "max angle between the optical axes (degrees)").Range(0, 180);
    s.Add("topk", &ProximityOptions::topk, "closest map images kept per image (0: all)").Min(0);
    s.Add("topk_revisit", &ProximityOptions::topk_revisit,
          "with topk: keep further neighbours until at least this many of an image's pairs are "
          "revisits (images taken >= revisit_min_dt_s apart: other sequences, loops), which the "
          "topk closest (mostly images of the same moment) may not contain")
        .Min(0);
    s.Add("revisit_min_dt_s", &ProximityOptions::revisit_min_dt_s,
          "time between two images of a revisit pair (s)").Min(0);
    s.Add("seconds_per_unit", &ProximityOptions::seconds_per_unit, "timestamp unit (s)").Range(1e-12, 1e6);
  }
};

class PoseProximityStage : public Stage<ProximityOptions> {
 public:
  static StageMeta Meta() {
    return {"pairs", "pose_proximity",
            "Pairs of images whose known poses are close (centre distance and viewing angle)",
            {{"map", "kapture.dataset", "map images with poses"},
             {"query", "kapture.dataset", "query images with poses (query-to-map mode)", LF_PORT_OPTIONAL}},
            {{"pairs", "kapture.pairs", "pairs.txt; score = 1 / (1 + distance in m)"}}};
  }
  using Stage::Stage;

  struct View {
    std::string image;
    Eigen::Vector3d centre, axis;
    double time_s = 0;
  };

  static std::vector<View> Views(const fs::path& dataset, double seconds_per_unit, RunContext& ctx) {
    k::Kapture kap(dataset);
    std::map<std::string, View> views;
    int64_t without_pose = 0;
    kap.ForEachDataRecord("camera", [&](const k::DataRecord& r) {
      const auto pose = kap.DevicePose(r.timestamp, r.device_id);
      if (!pose) return void(++without_pose);
      views[r.path] = {r.path, pose->Center(), pose->R().transpose() * Eigen::Vector3d::UnitZ(),
                       static_cast<double>(r.timestamp) * seconds_per_unit};
    });
    if (without_pose) ctx.Warn(std::to_string(without_pose) + " images without a pose in " + dataset.string());
    std::vector<View> out;
    for (auto& [name, v] : views) out.push_back(v);
    return out;
  }

  void Run(RunContext& ctx) override {
    const auto& o = options();
    const auto map = Views(ctx.Input("map"), o.seconds_per_unit, ctx);
    const bool query_mode = ctx.HasInput("query");
    const auto queries = query_mode ? Views(ctx.Input("query"), o.seconds_per_unit, ctx) : map;
    // Voxel hash of map centres, cell = max distance.
    const double cell = std::max(o.max_distance, 1e-3);
    auto key = [&](const Eigen::Vector3d& c) {
      return std::array<int64_t, 3>{int64_t(std::floor(c.x() / cell)), int64_t(std::floor(c.y() / cell)),
                                    int64_t(std::floor(c.z() / cell))};
    };
    std::map<std::array<int64_t, 3>, std::vector<int>> grid;
    for (int i = 0; i < static_cast<int>(map.size()); ++i) grid[key(map[i].centre)].push_back(i);
    const double cos_max = std::cos(o.max_angle_deg * M_PI / 180.0);
    std::vector<ScoredPair> pairs;
    std::set<std::pair<std::string, std::string>> seen;  // map-to-map: each unordered pair once
    for (const auto& q : queries) {
      // Every neighbour, whatever the name order: the top-k of an image must
      // not depend on how its neighbours' names sort.
      std::vector<std::pair<double, int>> near;
      const auto c = key(q.centre);
      for (int64_t dx = -1; dx <= 1; ++dx)
        for (int64_t dy = -1; dy <= 1; ++dy)
          for (int64_t dz = -1; dz <= 1; ++dz) {
            auto it = grid.find({c[0] + dx, c[1] + dy, c[2] + dz});
            if (it == grid.end()) continue;
            for (int m : it->second) {
              if (map[m].image == q.image) continue;
              const double d = (map[m].centre - q.centre).norm();
              if (d <= o.max_distance && map[m].axis.dot(q.axis) >= cos_max - 1e-12) near.emplace_back(d, m);
            }
          }
      std::sort(near.begin(), near.end());
      // The topk closest, plus the topk_revisit closest revisits not among them.
      std::vector<std::pair<double, int>> kept;
      int revisits = 0;
      for (size_t i = 0; i < near.size(); ++i) {
        const bool revisit = std::abs(map[near[i].second].time_s - q.time_s) >= o.revisit_min_dt_s;
        if (o.topk == 0 || static_cast<int>(i) < o.topk) {
          kept.push_back(near[i]);
        } else if (revisit && revisits < o.topk_revisit) {
          kept.push_back(near[i]);
        } else {
          continue;
        }
        revisits += revisit;
      }
      for (const auto& [d, m] : kept) {
        if (!query_mode) {
          const auto& a = std::min(q.image, map[m].image);
          const auto& b = std::max(q.image, map[m].image);
          if (!seen.insert({a, b}).second) continue;
        }
        pairs.push_back({q.image, map[m].image, 1.0 / (1.0 + d)});
      }
    }
    WritePairs(ctx.output_dir(), pairs);
  }
};

// --------------------------------------------------------------- pairs/file

struct PairsFileOptions {
  std::string path;
  static void Declare(ParamSchema<PairsFileOptions>& s) {
    s.Add("path", &PairsFileOptions::path, "pairs file: 'image1, image2[, score]' per line").Path().Required();
  }
};

class PairsFileStage : public Stage<PairsFileOptions> {
 public:
  static StageMeta Meta() {
    return {"pairs", "file", "Pairs from a kapture-localization pairs file (validated)",
            {},
            {{"pairs", "kapture.pairs", "pairs.txt"}}};
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

}  // namespace locforge::retrieval

LOCFORGE_PLUGIN("retrieval", "1.0.0", "DenseVLAD global descriptors, global feature import, image pair selection",
                locforge::retrieval::VocabularyStage, locforge::retrieval::DenseVladStage,
                locforge::retrieval::GlobalImportStage, locforge::retrieval::RetrievalStage,
                locforge::retrieval::ExhaustiveStage, locforge::retrieval::PoseProximityStage,
                locforge::retrieval::PairsFileStage)

// pipeline/colmap_vocab_tree: the classic COLMAP baseline in one stage:
// feature_extractor (SIFT) on the map, vocab_tree_builder (or a supplied
// tree), vocab_tree_matcher, point_triangulator on the fixed map poses, then
// the queries: feature_extractor, vocab_tree_matcher (queries against all),
// image_registrator. Same triangulator/registrator parameters as the other
// stages of this plugin. With matching = exhaustive (COLMAP's classic recipe
// for small maps): exhaustive_matcher over the map, then every query against
// every map image through matches_importer (no query x query pairs).
#include <map>
#include <sstream>

#include "locforge/colmap/database.h"
#include "locforge/colmap/model.h"
#include "locforge/colmap/run.h"
#include "locforge/kapture/kapture.h"
#include "locforge/params.h"
#include "locforge/plugin.h"
#include "locforge/colmap/kapture_database.h"

namespace locforge::pipeline {

using namespace locforge::colmap;

struct VocabTreeOptions {
  std::string vocab_tree;         // Supplied tree (.bin); "" = build one on the map.
  int num_visual_words = 4096;    // vocab_tree_builder words when building.
  int num_images = 100;           // VocabTreeMatching.num_images (neighbours per image).
  int max_num_features = 8192;    // SiftExtraction.max_num_features.
  std::string matching = "vocab_tree";  // vocab_tree | exhaustive (map x map, query x map).
  double timeout_s = 0;           // Kill a colmap step after this many seconds (0: never).
  static void Declare(ParamSchema<VocabTreeOptions>& s) {
    s.Add("matching", &VocabTreeOptions::matching,
          "vocab_tree: vocab_tree_matcher (map, then queries); exhaustive: every map pair, then every query x map "
          "pair (small maps; no tree)")
        .Choices({"vocab_tree", "exhaustive"});
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
    StageMeta meta = {"pipeline",
            "colmap_vocab_tree",
            "Classic COLMAP baseline: SIFT feature_extractor, vocab_tree_builder (or a supplied "
            "tree), vocab_tree_matcher (or exhaustive matching), point_triangulator on the map poses, "
            "image_registrator",
            {{"map", "kapture.dataset", "map images (records_data) with poses"},
             {"query", "kapture.dataset", "query images (records_data)"}},
            {{"trajectories", "kapture.trajectories", "registered query poses (+ failures.txt)"}},
            LF_STAGE_NONDETERMINISTIC};
    meta.version = "1.3.0";  // 1.3.0: damaged images refused
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;

 private:
  void Run(RunContext& ctx, const std::vector<std::string>& args, const std::string& tag);
  std::vector<std::string> Extract(RunContext& ctx, const fs::path& db, const fs::path& images,
                                   const fs::path& list, const std::string& tag);
  // The steps of Run.
  std::vector<kapture::DataRecord> BuildMap(RunContext& ctx, kapture::Kapture& map,
                                            std::vector<std::string>* match_common);
  std::vector<kapture::DataRecord> RegisterQueries(RunContext& ctx, kapture::Kapture& query,
                                                   const std::vector<kapture::DataRecord>& map_records,
                                                   const std::vector<std::string>& match_common);
  std::vector<std::string> SiftMatchingArgs(RunContext& ctx) const;
  std::map<std::string, double> seconds_;
};

namespace {

namespace kp = locforge::kapture;

// COLMAP decodes with FreeImage, which reads a damaged file as far as it can
// without failing: such images are refused first, all of them named.
void RefuseDamagedImages(const kp::Kapture& k) {
  const auto damaged = kp::FindDamagedImages(k);
  if (damaged.empty()) return;
  constexpr size_t kShown = 5;
  std::string listed;
  for (size_t i = 0; i < damaged.size() && i < kShown; ++i)
    listed += (i ? "; " : "") + damaged[i].path + ": " + damaged[i].reason;
  if (damaged.size() > kShown) listed += "; and " + std::to_string(damaged.size() - kShown) + " more";
  throw InputError(kp::layout::RecordsFile(kp::kSensorCamera), 0, "image_path",
                   std::to_string(damaged.size()) + " damaged images: " + listed);
}

// Adds cameras (from sensors.txt, so intrinsics are the dataset's) and
// images (no keypoints yet); feature_extractor then fills the features.
std::vector<kp::DataRecord> AddDatasetImages(const kp::Kapture& k, Database* db,
                                             const fs::path& list_file) {
  auto records = k.ReadDataRecords(kp::kSensorCamera);
  RefuseDamagedImages(k);
  std::map<std::string, colmap::CameraId> cameras;
  std::ostringstream list;
  db->BeginTransaction();
  for (const auto& r : records) {
    if (!cameras.count(r.device_id)) {
      const kp::Sensor* s = k.sensors().Find(r.device_id);
      if (!s || !s->camera || s->camera->model == CameraModelId::kUnknown)
        throw InputError("sensors/sensors.txt", 0, r.device_id, "camera with a COLMAP model needed");
      colmap::DbCamera c;
      c.camera = *s->camera;
      c.prior_focal_length = true;
      cameras[r.device_id] = db->WriteCamera(c, false);
    }
    colmap::DbImage image;
    image.name = r.path;
    image.camera_id = cameras.at(r.device_id);
    db->WriteImage(image, false);
    list << r.path << "\n";
  }
  db->CommitTransaction();
  WriteFileAtomic(list_file, list.str());
  return records;
}

}  // namespace

std::vector<std::string> VocabTreeStage::Extract(RunContext& ctx, const fs::path& db,
                                                 const fs::path& images, const fs::path& list,
                                                 const std::string& tag) {
  std::vector<std::string> a = {"feature_extractor", "--database_path", db.string(),
                                "--image_path", images.string(), "--image_list_path",
                                list.string(), "--SiftExtraction.use_gpu", "0",
                                "--SiftExtraction.num_threads", std::to_string(ctx.threads()),
                                "--SiftExtraction.max_num_features",
                                std::to_string(options().max_num_features)};
  Run(ctx, a, "feature_extractor_" + tag);
  return a;
}

void VocabTreeStage::Run(RunContext& ctx, const std::vector<std::string>& args,
                         const std::string& tag) {
  const auto r = colmap::RunColmap(args, RunOptionsFor(ctx, tag, options().timeout_s));
  ctx.Info("colmap " + args.front() + ": " + FormatDouble(r.seconds) + " s");
  seconds_[tag] = r.seconds;
}

namespace {

// A fixed-pose model of the map database's images with COLMAP's ids and
// keypoints (the images without a pose left out).
colmap::Reconstruction FixedPoseModel(const fs::path& map_db, kp::Kapture& map,
                                      const std::vector<kp::DataRecord>& map_records) {
  colmap::Reconstruction input;
  Database db(map_db, Database::Mode::kReadOnly);
  for (const auto& c : db.ReadCameras()) input.cameras.push_back({c.camera_id, c.camera});
  std::map<std::string, const kp::DataRecord*> by_name;
  for (const auto& r : map_records) by_name[r.path] = &r;
  for (const auto& im : db.ReadImages()) {
    const kp::DataRecord* r = by_name.at(im.name);
    const auto pose = map.DevicePose(r->timestamp, r->device_id);
    if (!pose) continue;
    colmap::ModelImage mi;
    mi.image_id = im.image_id;
    mi.camera_id = im.camera_id;
    mi.name = im.name;
    mi.SetCameraFromWorld(*pose);
    const auto kpts = db.ReadKeypoints(im.image_id);
    if (kpts)
      for (uint32_t i = 0; i < kpts->rows; ++i) {
        colmap::Point2D p;
        p.xy = Eigen::Vector2d(kpts->at(i, 0), kpts->at(i, 1));
        mi.points2d.push_back(p);
      }
    input.images.push_back(std::move(mi));
  }
  return input;
}

// Every query x map pair, by name (matches_importer's pair list).
std::string QueryPairs(const std::vector<kp::DataRecord>& query_records,
                       const std::vector<kp::DataRecord>& map_records) {
  std::ostringstream pairs;
  for (const auto& q : query_records)
    for (const auto& m : map_records) pairs << q.path << " " << m.path << "\n";
  return pairs.str();
}

}  // namespace

// The map: its images into map.db, features, a vocabulary tree (unless
// exhaustive or given), matches, and points triangulated at the fixed poses.
// The map's records; match_common: the matcher options the queries share.
std::vector<kp::DataRecord> VocabTreeStage::BuildMap(RunContext& ctx, kp::Kapture& map,
                                                     std::vector<std::string>* match_common) {
  const auto& o = options();
  const fs::path out = ctx.output_dir();
  const fs::path map_db = out / "map.db";
  std::vector<kp::DataRecord> map_records;
  {
    Database db(map_db, Database::Mode::kCreate);
    map_records = AddDatasetImages(map, &db, out / "map_images.txt");
  }
  Extract(ctx, map_db, map.root() / kp::layout::kRecordsData, out / "map_images.txt", "map");
  const bool exhaustive = o.matching == "exhaustive";
  fs::path tree = o.vocab_tree;
  if (tree.empty() && !exhaustive) {
    tree = out / "vocab_tree.bin";
    Run(ctx, {"vocab_tree_builder", "--database_path", map_db.string(), "--vocab_tree_path",
              tree.string(), "--num_visual_words", std::to_string(o.num_visual_words)},
        "vocab_tree_builder");
  }
  *match_common = SiftMatchingArgs(ctx);
  if (!exhaustive)
    match_common->insert(match_common->end(), {"--VocabTreeMatching.vocab_tree_path", tree.string(),
                                                "--VocabTreeMatching.num_images", std::to_string(o.num_images)});
  std::vector<std::string> a = {exhaustive ? "exhaustive_matcher" : "vocab_tree_matcher", "--database_path",
                                map_db.string()};
  a.insert(a.end(), match_common->begin(), match_common->end());
  Run(ctx, a, exhaustive ? "exhaustive_matcher_map" : "vocab_tree_matcher_map");
  colmap::WriteModelText(FixedPoseModel(map_db, map, map_records), out / "input_model");
  fs::create_directories(out / "map_model");
  a = {"point_triangulator", "--database_path", map_db.string(), "--input_path",
       (out / "input_model").string(), "--output_path", (out / "map_model").string(),
       "--clear_points", "1", "--image_path", (map.root() / kp::layout::kRecordsData).string()};
  AddFixedIntrinsics(&a);
  kPaperTriangulator.AddTo(&a);
  Run(ctx, a, "point_triangulator");
  return map_records;
}

std::vector<std::string> VocabTreeStage::SiftMatchingArgs(RunContext& ctx) const {
  return {"--SiftMatching.use_gpu", "0", "--SiftMatching.num_threads", std::to_string(ctx.threads())};
}

// The queries: into a copy of the map's database, features, matches
// against the map (every pair when exhaustive), registration.
std::vector<kp::DataRecord> VocabTreeStage::RegisterQueries(RunContext& ctx, kp::Kapture& query,
                                                            const std::vector<kp::DataRecord>& map_records,
                                                            const std::vector<std::string>& match_common) {
  const fs::path out = ctx.output_dir();
  const fs::path db_path = out / "database.db";
  fs::copy_file(out / "map.db", db_path, fs::copy_options::overwrite_existing);
  std::vector<kp::DataRecord> query_records;
  {
    Database db(db_path, Database::Mode::kReadWrite);
    query_records = AddDatasetImages(query, &db, out / "query_images.txt");
  }
  Extract(ctx, db_path, query.root() / kp::layout::kRecordsData, out / "query_images.txt", "query");
  std::vector<std::string> a;
  if (options().matching == "exhaustive") {
    WriteFileAtomic(out / "query_pairs.txt", QueryPairs(query_records, map_records));
    a = {"matches_importer", "--database_path", db_path.string(), "--match_list_path",
         (out / "query_pairs.txt").string(), "--match_type", "pairs"};
    const std::vector<std::string> sift_matching = SiftMatchingArgs(ctx);
    a.insert(a.end(), sift_matching.begin(), sift_matching.end());
    Run(ctx, a, "matches_importer_query");
  } else {
    a = {"vocab_tree_matcher", "--database_path", db_path.string(),
         "--VocabTreeMatching.match_list_path", (out / "query_images.txt").string()};
    a.insert(a.end(), match_common.begin(), match_common.end());
    Run(ctx, a, "vocab_tree_matcher_query");
  }
  fs::create_directories(out / "model");
  a = {"image_registrator", "--database_path", db_path.string(), "--input_path",
       (out / "map_model").string(), "--output_path", (out / "model").string()};
  AddFixedIntrinsics(&a);
  kPaperRegistrator.AddTo(&a);
  Run(ctx, a, "image_registrator");
  return query_records;
}

void VocabTreeStage::Run(RunContext& ctx) {
  const fs::path out = ctx.output_dir();
  kp::Kapture map(ctx.Input("map")), query(ctx.Input("query"));
  std::vector<std::string> match_common;
  const std::vector<kp::DataRecord> map_records = BuildMap(ctx, map, &match_common);
  const std::vector<kp::DataRecord> query_records = RegisterQueries(ctx, query, map_records, match_common);
  const colmap::Reconstruction model = colmap::ReadModel(out / "model");
  const int ok = WriteRegisteredQueries(model, query, query_records, out);
  std::ostringstream times;
  times << "step,seconds\n";
  for (const auto& [tag, s] : seconds_) times << tag << "," << FormatDouble(s) << "\n";
  WriteFileAtomic(out / "colmap_seconds.csv", times.str());
  ctx.Info("vocab-tree baseline registered " + std::to_string(ok) + " of " +
           std::to_string(query_records.size()) + " queries");
}

LOCFORGE_REGISTER_STAGE(VocabTreeStage)

}  // namespace locforge::pipeline

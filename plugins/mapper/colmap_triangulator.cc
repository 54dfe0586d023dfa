// mapper/colmap_triangulator and localizer/colmap_registrator: COLMAP 3.8
// `point_triangulator` / `image_registrator` on a database we fill from
// kapture artifacts, with the paper's parameters.
#include <chrono>
#include <regex>
#include <sstream>

#include "colmap_db.h"
#include "kapture_merge.h"
#include "vocab_tree.h"
#include "locforge/colmap/convert.h"
#include "locforge/colmap/model.h"
#include "locforge/colmap/run.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::colmap_stages {
namespace {

namespace kp = locforge::kapture;

// The Mapper options of point_triangulator / image_registrator, defaulting to
// the paper's values for that tool (kPaperTriangulator / kPaperRegistrator).
template <const MapperParams& kDefaults>
struct MapperOptions {
  int min_num_matches = kDefaults.min_num_matches;
  int init_min_num_inliers = kDefaults.init_min_num_inliers;
  int abs_pose_min_num_inliers = kDefaults.abs_pose_min_num_inliers;
  double abs_pose_min_inlier_ratio = kDefaults.abs_pose_min_inlier_ratio;
  int ba_local_max_num_iterations = kDefaults.ba_local_max_num_iterations;
  double abs_pose_max_error = kDefaults.abs_pose_max_error;
  double filter_max_reproj_error = kDefaults.filter_max_reproj_error;
  std::string keypoints_type;  // empty = the features' only keypoints type
  double timeout_s = 0;        // kill colmap after this many seconds (0: never)
  static void Declare(ParamSchema<MapperOptions>& s) {
    using O = MapperOptions;
    s.Add("min_num_matches", &O::min_num_matches, "Mapper.min_num_matches").Min(1);
    s.Add("init_min_num_inliers", &O::init_min_num_inliers, "Mapper.init_min_num_inliers").Min(1);
    s.Add("abs_pose_min_num_inliers", &O::abs_pose_min_num_inliers,
          "Mapper.abs_pose_min_num_inliers").Min(3);
    s.Add("abs_pose_min_inlier_ratio", &O::abs_pose_min_inlier_ratio,
          "Mapper.abs_pose_min_inlier_ratio").Range(0, 1);
    s.Add("ba_local_max_num_iterations", &O::ba_local_max_num_iterations,
          "Mapper.ba_local_max_num_iterations").Min(0);
    s.Add("abs_pose_max_error", &O::abs_pose_max_error, "Mapper.abs_pose_max_error (px)").Min(0.01);
    s.Add("filter_max_reproj_error", &O::filter_max_reproj_error,
          "Mapper.filter_max_reproj_error (px)").Min(0.01);
    s.Add("keypoints_type", &O::keypoints_type, "keypoints type; empty = the only one");
    s.Add("timeout_s", &O::timeout_s, "kill colmap after this many seconds (0: never)").Min(0).NoCacheKey();
  }
  MapperParams Mapper() const {
    return {min_num_matches, init_min_num_inliers, abs_pose_min_num_inliers,
            abs_pose_min_inlier_ratio, ba_local_max_num_iterations, abs_pose_max_error,
            filter_max_reproj_error};
  }
};
using TriangulatorOptions = MapperOptions<kPaperTriangulator>;
using RegistratorOptions = MapperOptions<kPaperRegistrator>;

// COLMAP reads the images only for point colours: the dataset's records_data
// when present, else an empty folder (points come out grey).
fs::path ImagePath(const fs::path& dataset, const fs::path& out) {
  const fs::path images = dataset / kp::layout::kRecordsData;
  if (fs::is_directory(images)) return images;
  fs::create_directories(out / "no_images");
  return out / "no_images";
}

class ColmapTriangulator : public Stage<TriangulatorOptions> {
 public:
  static StageMeta Meta() {
    return {"mapper",
            "colmap_triangulator",
            "COLMAP point_triangulator on a database + fixed-pose model built from the map "
            "kapture (rig poses composed), the paper's parameters; intrinsics fixed",
            {{"map", "kapture.dataset", "map images with poses"},
             {"features", "kapture.local_features", "map keypoints"},
             {"matches", "kapture.matches", "verified map-to-map matches"}},
            {{"model", "colmap.model", "model/ + database.db"},
             {"reconstruction", "kapture.reconstruction", "reconstruction/points3d.txt + observations.txt"}}};
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const auto& o = options();
    const fs::path out = ctx.output_dir();
    kp::Kapture map(ctx.Input("map"));
    kp::Kapture features(ctx.Input("features"));
    kp::Kapture matches(ctx.Input("matches"));
    const std::string type = KeypointsType(features, o.keypoints_type);
    const fs::path db_path = out / "database.db";
    DbImages ids;
    {
      colmap::Database db(db_path, colmap::Database::Mode::kCreate);
      colmap::DatabaseWriter writer(&db);
      ids = AddImages(map, features, type, &writer);
      const int64_t pairs = AddMatches(matches, type, ids.id_of, {}, &writer);
      writer.Finish();
      ctx.Info(std::to_string(ids.id_of.size()) + " map images, " + std::to_string(pairs) +
               " matched pairs in the database");
    }
    // Fixed-pose input model: every posed map image, no points.
    colmap::Reconstruction input;
    for (const auto& [sensor, camera_id] : ids.camera_of)
      input.cameras.push_back({camera_id, *map.sensors().Find(sensor)->camera});
    int unposed = 0;
    for (const auto& r : map.ReadDataRecords(kp::kSensorCamera)) {
      const auto pose = map.DevicePose(r.timestamp, r.device_id);
      if (!pose) {
        ++unposed;
        continue;
      }
      colmap::ModelImage image;
      image.image_id = ids.id_of.at(r.path);
      image.camera_id = ids.camera_of.at(r.device_id);
      image.name = r.path;
      image.SetCameraFromWorld(*pose);
      image.points2d.resize(ids.num_keypoints.at(image.image_id));
      const auto kpts = features.ReadKeypoints(type, r.path);
      for (int64_t i = 0; i < kpts.rows; ++i)
        image.points2d[i].xy = Eigen::Vector2d(kpts.At(i, 0), kpts.At(i, 1));
      input.images.push_back(std::move(image));
    }
    if (input.images.empty())
      throw InputError(ctx.Input("map").string(), 0, "trajectories", "no map image has a pose");
    if (unposed) ctx.Warn(std::to_string(unposed) + " map images without pose left out");
    colmap::WriteModelText(input, out / "input_model");
    fs::create_directories(out / "model");
    std::vector<std::string> args = {"point_triangulator", "--database_path", db_path.string(),
                                     "--input_path", (out / "input_model").string(),
                                     "--output_path", (out / "model").string(),
                                     "--clear_points", "1", "--image_path",
                                     ImagePath(ctx.Input("map"), out).string()};
    AddFixedIntrinsics(&args);
    o.Mapper().AddTo(&args);
    const auto run = colmap::RunColmap(args, RunOptionsFor(ctx, "point_triangulator", o.timeout_s));
    const colmap::Reconstruction model = colmap::ReadModel(out / "model");
    colmap::WriteKapturePoints(model, type, out);
    ctx.Info("point_triangulator: " + std::to_string(model.points3d.size()) + " points in " +
             std::to_string(run.seconds) + " s");
  }

};

class ColmapRegistrator : public Stage<RegistratorOptions> {
 public:
  static StageMeta Meta() {
    return {"localizer",
            "colmap_registrator",
            "COLMAP image_registrator: query images + keypoints + query-to-map matches added to "
            "a copy of the map database, P3P RANSAC + pose refinement (paper's parameters, "
            "intrinsics fixed); unregistered queries listed in failures.txt",
            {{"model", "colmap.model", "the map's model/ + database.db (mapper/colmap_triangulator)"},
             {"query", "kapture.dataset", "query sensors and records_camera"},
             {"query_features", "kapture.local_features", "query keypoints"},
             {"matches", "kapture.matches", "query-to-map matches"}},
            {{"trajectories", "kapture.trajectories", "registered query poses (+ failures.txt)"}}};
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const auto& o = options();
    const fs::path out = ctx.output_dir();
    const fs::path map_model = ctx.Input("model");
    kp::Kapture query(ctx.Input("query"));
    kp::Kapture features(ctx.Input("query_features"));
    kp::Kapture matches(ctx.Input("matches"));
    const std::string type = KeypointsType(features, o.keypoints_type);
    const fs::path db_path = out / "database.db";
    fs::copy_file(map_model / "database.db", db_path, fs::copy_options::overwrite_existing);
    DbImages query_ids;
    {
      colmap::Database db(db_path, colmap::Database::Mode::kReadWrite);
      std::map<std::string, colmap::ImageId> all;
      for (const auto& image : db.ReadImages()) all[image.name] = image.image_id;
      colmap::DatabaseWriter writer(&db);
      query_ids = AddImages(query, features, type, &writer);
      for (const auto& [name, id] : query_ids.id_of) all[name] = id;
      const int64_t pairs = AddMatches(matches, type, all, query_ids.id_of, &writer);
      writer.Finish();
      ctx.Info(std::to_string(query_ids.id_of.size()) + " queries, " + std::to_string(pairs) +
               " query-to-map pairs");
    }
    fs::create_directories(out / "model");
    std::vector<std::string> args = {"image_registrator", "--database_path", db_path.string(),
                                     "--input_path", (map_model / "model").string(),
                                     "--output_path", (out / "model").string()};
    AddFixedIntrinsics(&args);
    o.Mapper().AddTo(&args);
    const auto run = colmap::RunColmap(args, RunOptionsFor(ctx, "image_registrator", o.timeout_s));
    const colmap::Reconstruction model = colmap::ReadModel(out / "model");
    const std::vector<kp::DataRecord> records = query.ReadDataRecords(kp::kSensorCamera);
    const int total = static_cast<int>(records.size());
    const int ok = WriteRegisteredQueries(model, query, records, out);
    WriteFileAtomic(out / "localization_stats.csv",
                    "queries,registered,colmap_seconds,seconds_per_query\n" +
                        std::to_string(total) + "," + std::to_string(ok) + "," +
                        FormatDouble(run.seconds) + "," +
                        FormatDouble(total ? run.seconds / total : 0) + "\n");
    ctx.Info("image_registrator registered " + std::to_string(ok) + " of " +
             std::to_string(total) + " queries in " + std::to_string(run.seconds) + " s");
  }
};


struct KaptureFolderOptions {
  std::string path;                // The kapture root to bring into the graph.
  bool copy_records_data = true;   // Copy images etc. (needed by stages reading pixels).
  std::vector<std::string> subfolders;  // Kapture roots under `path` merged into one (cameras only).
  std::string images;              // Regex: keep only the images whose path matches (cameras only).
  static void Declare(ParamSchema<KaptureFolderOptions>& s) {
    s.Add("path", &KaptureFolderOptions::path, "kapture root (sensors/, reconstruction/)").Path().Required();
    s.Add("copy_records_data", &KaptureFolderOptions::copy_records_data,
          "copy sensors/records_data (images); off when only features are used");
    s.Add("subfolders", &KaptureFolderOptions::subfolders,
          "kapture roots under `path` merged into one camera dataset, image paths prefixed "
          "with the sub-folder (e.g. [validation, test] of a simulator recording; \".\" is "
          "`path` itself, unprefixed); sensors, rigs, trajectories and camera records only. "
          "Empty: `path` copied whole");
    s.Add("images", &KaptureFolderOptions::images,
          "regular expression on image paths (after the sub-folder prefix): keep only the images "
          "it matches whole, with their poses; cameras only (e.g. \"map_.*\" and \"(val|test)_.*\" "
          "split one ground-truth kapture into map and queries). Empty: all");
  }
  bool Check(std::string* why) const {
    for (const auto& sub : subfolders)
      if (sub.empty() || fs::path(sub).is_absolute() || sub.find("..") != std::string::npos)
        return *why = "subfolders: '" + sub + "' is not a relative folder under path", false;
    try {
      std::regex(images);
    } catch (const std::regex_error& e) {
      return *why = "images: '" + images + "' is not a regular expression: " + e.what(), false;
    }
    return true;
  }
};

// Brings a kapture folder into a graph as a kapture.dataset artifact: text
// files parsed and re-emitted (so a malformed dataset fails here, naming the
// file and line), records data copied when asked.
class KaptureFolder : public Stage<KaptureFolderOptions> {
 public:
  static StageMeta Meta() {
    return {"source", "kapture_folder", "A kapture dataset folder (e.g. the map or the queries)",
            {}, {{"dataset", "kapture.dataset", "the dataset, re-emitted"}}};
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override {
    if (!options().subfolders.empty() || !options().images.empty()) {
      std::vector<MergeSource> sources;
      if (options().subfolders.empty()) sources.push_back({fs::path(options().path), ""});
      for (const auto& sub : options().subfolders)
        sources.push_back({sub == "." ? fs::path(options().path) : fs::path(options().path) / sub,
                           sub == "." ? "" : fs::path(sub).generic_string()});
      const MergeReport r =
          MergeCameraKaptures(sources, ctx.output_dir(), options().copy_records_data, options().images);
      std::string subs;
      for (const auto& sub : options().subfolders) subs += (subs.empty() ? "" : ", ") + sub;
      ctx.Info("kapture " + options().path + " [" + subs + "] merged: " +
               std::to_string(r.sensors) + " sensors, " + std::to_string(r.images) + " images, " +
               std::to_string(r.poses) + " poses, " + std::to_string(r.data_files) +
               " image files");
      return;
    }
    kp::CopyOptions o;
    o.copy_records_data = options().copy_records_data;
    o.overwrite = true;
    const auto report = kp::CopyKapture(options().path, ctx.output_dir(), o);
    ctx.Info("kapture " + options().path + ": " + std::to_string(report.records) + " records, " +
             std::to_string(report.data_files) + " data files copied");
  }
};

}  // namespace
}  // namespace locforge::colmap_stages

LOCFORGE_PLUGIN("colmap_stages", "1.1.0",
                "COLMAP point_triangulator / image_registrator stages (paper's parameters)",
                locforge::colmap_stages::ColmapTriangulator,
                locforge::colmap_stages::ColmapRegistrator,
                locforge::colmap_stages::KaptureFolder,
                locforge::colmap_stages::VocabTreeStage)

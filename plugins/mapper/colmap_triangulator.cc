// mapper/colmap_triangulator: COLMAP 3.8 point_triangulator on a database
// filled from kapture artifacts, with the paper's parameters.
#include <chrono>
#include <regex>
#include <sstream>

#include "locforge/colmap/convert.h"
#include "locforge/colmap/kapture_database.h"
#include "locforge/colmap/model.h"
#include "locforge/colmap/run.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::mapper {

namespace {

namespace kp = locforge::kapture;
using namespace locforge::colmap;

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
    StageMeta meta = {"mapper",
            "colmap_triangulator",
            "COLMAP point_triangulator on a database + fixed-pose model built from the map "
            "kapture (rig poses composed), the paper's parameters; intrinsics fixed",
            {{"map", "kapture.dataset", "map images with poses"},
             {"features", "kapture.local_features", "map keypoints"},
             {"matches", "kapture.matches", "verified map-to-map matches"}},
            {{"model", "colmap.model", "model/ + database.db"},
             {"reconstruction", "kapture.reconstruction", "reconstruction/points3d.txt + observations.txt"}}};
    meta.version = "1.1.0";
    return meta;
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

}  // namespace

LOCFORGE_REGISTER_STAGE(ColmapTriangulator)

}  // namespace locforge::mapper

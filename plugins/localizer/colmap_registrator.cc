// localizer/colmap_registrator: COLMAP 3.8 image_registrator of the queries
// into a triangulated map, with the paper's parameters.
#include <chrono>
#include <regex>
#include <sstream>

#include "locforge/colmap/convert.h"
#include "locforge/colmap/kapture_database.h"
#include "locforge/colmap/model.h"
#include "locforge/colmap/run.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::localizer {

namespace {

namespace kp = locforge::kapture;
using namespace locforge::colmap;

class ColmapRegistrator : public Stage<RegistratorOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"localizer",
            "colmap_registrator",
            "COLMAP image_registrator: query images + keypoints + query-to-map matches added to "
            "a copy of the map database, P3P RANSAC + pose refinement (paper's parameters, "
            "intrinsics fixed); unregistered queries listed in failures.txt",
            {{"model", "colmap.model", "the map's model/ + database.db (mapper/colmap_triangulator)"},
             {"query", "kapture.dataset", "query sensors and records_camera"},
             {"query_features", "kapture.local_features", "query keypoints"},
             {"matches", "kapture.matches", "query-to-map matches"}},
            {{"trajectories", "kapture.trajectories", "registered query poses (+ failures.txt)"}}};
    meta.version = "1.1.0";
    return meta;
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

}  // namespace

LOCFORGE_REGISTER_STAGE(ColmapRegistrator)

}  // namespace locforge::localizer

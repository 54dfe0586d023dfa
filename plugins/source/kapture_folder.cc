// source/kapture_folder: a kapture folder brought into a graph (re-emitted,
// or merged from sub-folders; kapture_folder/kapture_merge.h).
#include <chrono>
#include <regex>
#include <sstream>

#include "locforge/colmap/convert.h"
#include "locforge/colmap/kapture_database.h"
#include "locforge/colmap/model.h"
#include "locforge/colmap/run.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "kapture_merge.h"

namespace locforge::source {

using namespace ::locforge::colmap_stages;  // the library this stage wires

namespace {

namespace kp = locforge::kapture;
using namespace locforge::colmap;

struct KaptureFolderOptions {
  std::string path;                // The kapture root to bring into the graph.
  bool copy_records_data = true;   // Copy images etc. (needed by stages reading pixels).
  std::vector<std::string> subfolders;  // Kapture roots under `path` merged into one (cameras only).
  std::string images;              // Regex: keep only the images whose path matches (cameras only).
  int sample_every = 1;            // Of those, 1 in N per camera in time order (a sparse map).
  bool sample_rest = false;        // Keep the other N-1 of every N instead (its queries).
  static void Declare(ParamSchema<KaptureFolderOptions>& s) {
    s.Add("path", &KaptureFolderOptions::path,
          "kapture root (sensors/, reconstruction/), or wire the kapture input").Path();
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
    s.Add("sample_every", &KaptureFolderOptions::sample_every,
          "of the images kept, one in every N of each camera in time order (the 1st, the N+1-th, "
          "...), with their poses; cameras only. E.g. 4: a sparse map of a recording. 1: all")
        .Range(1, 1000);
    s.Add("sample_rest", &KaptureFolderOptions::sample_rest,
          "keep the other N-1 of every `sample_every` instead: the images a sparse map leaves "
          "out, localized as its queries (the two selections partition the images)");
  }
  bool Check(std::string* why) const {
    for (const auto& sub : subfolders)
      if (sub.empty() || fs::path(sub).is_absolute() || sub.find("..") != std::string::npos)
        return *why = "subfolders: '" + sub + "' is not a relative folder under path", false;
    try {
      const std::regex valid(images);  // (`std::regex(images);` would declare a variable)
      (void)valid;
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
    StageMeta meta = {"source", "kapture_folder", "A kapture dataset folder (e.g. the map or the queries)",
            {{"kapture", "kapture.dataset", "the kapture root, instead of the path parameter (e.g. a ground truth "
              "made in the same graph)", LF_PORT_OPTIONAL}},
            {{"dataset", "kapture.dataset", "the dataset, re-emitted"}}};
    meta.version = "1.2.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override {
    const fs::path root = ctx.PathOrInput("source/kapture_folder", "path", options().path, "kapture");
    if (!options().subfolders.empty() || !options().images.empty() || options().sample_every > 1) {
      std::vector<MergeSource> sources;
      if (options().subfolders.empty()) sources.push_back({root, ""});
      for (const auto& sub : options().subfolders)
        sources.push_back({sub == "." ? root : root / sub,
                           sub == "." ? "" : fs::path(sub).generic_string()});
      const MergeReport r =
          MergeCameraKaptures(sources, ctx.output_dir(), options().copy_records_data,
                              {options().images, options().sample_every, options().sample_rest});
      std::string subs;
      for (const auto& sub : options().subfolders) subs += (subs.empty() ? "" : ", ") + sub;
      ctx.Info("kapture " + root.string() + " [" + subs + "] merged: " +
               std::to_string(r.sensors) + " sensors, " + std::to_string(r.images) + " images, " +
               std::to_string(r.poses) + " poses, " + std::to_string(r.data_files) +
               " image files");
      return;
    }
    kp::CopyOptions o;
    o.copy_records_data = options().copy_records_data;
    o.overwrite = true;
    const auto report = kp::CopyKapture(root, ctx.output_dir(), o);
    ctx.Info("kapture " + root.string() + ": " + std::to_string(report.records) + " records, " +
             std::to_string(report.data_files) + " data files copied");
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(KaptureFolder)

}  // namespace locforge::source

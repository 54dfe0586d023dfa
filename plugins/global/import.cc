// global/import: existing kapture global features as an artifact.
#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <opencv2/core.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "densevlad.h"
#include "densevlad_io.h"
#include "global_features.h"
#include "locforge/kapture/csv.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::global {

using namespace ::locforge::retrieval;  // the library this stage wires

namespace {

namespace k = locforge::kapture;

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
    StageMeta meta = {"global", "import", "Imports an existing kapture global features folder (validated copy)",
            {},
            {{"features", "kapture.global_features", "the imported global features"}}};
    meta.version = "1.0.0";
    return meta;
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

}  // namespace

LOCFORGE_REGISTER_STAGE(GlobalImportStage)

}  // namespace locforge::global

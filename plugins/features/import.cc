// features/import: an existing kapture feature folder as a
// kapture.local_features artifact (validated copy).
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::features {

namespace {

namespace k = locforge::kapture;

struct ImportOptions {
  std::string path;  // Feature folder: <path>/keypoints + <path>/descriptors.
  std::string type;  // Type name in the artifact; "" = the keypoints type of the folder.
  static void Declare(ParamSchema<ImportOptions>& s) {
    s.Add("path", &ImportOptions::path,
          "folder holding keypoints/ and descriptors/ (kapture-localization's "
          "local_features/<type>), or a kapture root with reconstruction/keypoints/<type>")
        .Path()
        .Required();
    s.Add("type", &ImportOptions::type,
          "feature type to import from a kapture root / name in the output (default: the folder's)");
  }
  bool Check(std::string* why) const {
    if (!type.empty() && !kapture::IsFeatureTypeName(type)) {
      *why = "parameter 'type': '" + type + "' is not a folder name";
      return false;
    }
    return true;
  }
};

class ImportStage : public Stage<ImportOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"features", "import",
            "Imports an existing kapture keypoints + descriptors folder (validated copy)",
            {},
            {{"features", "kapture.local_features", "the imported keypoints + descriptors"}}};
    meta.version = "1.1.0";
    return meta;
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const fs::path src = fs::absolute(options().path);
    fs::path kpt_dir, desc_dir;
    std::string type = options().type;
    if (fs::is_directory(src / "keypoints") && fs::exists(src / "keypoints" / "keypoints.txt")) {
      kpt_dir = src / "keypoints";
      desc_dir = src / "descriptors";
      if (type.empty()) type = src.filename().string();
    } else if (fs::is_directory(src / "reconstruction")) {
      k::Kapture kap(src);
      const auto sets = kap.FeatureSets(k::FeatureKind::kKeypoints);
      if (type.empty()) {
        if (sets.size() != 1)
          throw InputError(src.string(), 0, "type",
                           std::to_string(sets.size()) + " keypoints types here; set 'type'");
        type = sets.front().type;
      }
      kpt_dir = kap.GetFeatureSet(k::FeatureKind::kKeypoints, type).dir;
      desc_dir = kap.GetFeatureSet(k::FeatureKind::kDescriptors, type).dir;
    } else {
      throw InputError(src.string(), 0, "path",
                       "neither keypoints/keypoints.txt nor a kapture reconstruction/ here");
    }
    if (!fs::exists(desc_dir / "descriptors.txt"))
      throw InputError((desc_dir / "descriptors.txt").string(), 0, "", "missing");
    if (!kapture::IsFeatureTypeName(type)) throw InputError(src.string(), 0, "type", "'" + type + "' is not a folder name");
    const fs::path out = ctx.output_dir();
    const fs::path out_kpt = out / k::layout::FeatureRoot(k::FeatureKind::kKeypoints) / type;
    const fs::path out_desc = out / k::layout::FeatureRoot(k::FeatureKind::kDescriptors) / type;
    const int64_t nk = k::CopyFeatureFolder(k::FeatureKind::kKeypoints, kpt_dir, out_kpt, true);
    const int64_t nd = k::CopyFeatureFolder(k::FeatureKind::kDescriptors, desc_dir, out_desc, true);
    // The descriptors must name the keypoints type they now live beside.
    k::FeatureInfo dinfo = k::ReadFeatureInfo(out_desc / "descriptors.txt", k::FeatureKind::kDescriptors);
    if (dinfo.keypoints_type != type) {
      dinfo.keypoints_type = type;
      k::WriteFeatureSetInfo(out, type, dinfo);
    }
    ctx.Info("imported " + std::to_string(nk) + " keypoints and " + std::to_string(nd) +
             " descriptors files of type '" + type + "'");
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(ImportStage)

}  // namespace locforge::features

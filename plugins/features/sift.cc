// Stages: features/sift (per image) and features/import (an existing kapture
// feature folder as a kapture.local_features artifact).
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "sift.h"

namespace locforge::sift {

namespace {

namespace k = locforge::kapture;

// keypoints "SIFT" float32 x 4 (x, y, scale, orientation); descriptors
// "RootSIFT" or "SIFT" of descriptor_dtype x 128.
k::LocalFeatureInfos Infos(const SiftOptions& o) {
  k::DType dtype = k::DType::kUint8;
  k::ParseDType(o.descriptor_dtype, &dtype);
  return k::MakeLocalFeatureInfos(o.type, "SIFT", 4, dtype, 128, "L2",
                                  o.root_sift ? "RootSIFT" : "SIFT");
}

}  // namespace

class SiftStage : public PerItemStage<SiftOptions> {
 public:
  static StageMeta Meta() {
    return {"features", "sift", "OpenCV SIFT keypoints and (Root)SIFT descriptors per image",
            {{"images", "kapture.dataset", "images to describe (records_camera.txt)"}},
            {{"features", "kapture.local_features", "keypoints + descriptors of one type"}}};
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override {
    return k::Kapture(ctx.Input("images")).CameraImages();
  }

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const fs::path file =
        k::Kapture(ctx.Input("images")).RecordDataPath(image, k::layout::RecordsFile("camera"));
    const cv::Mat gray = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
    if (gray.empty())
      throw InputError(k::layout::RecordsFile("camera"), 0, "image_path",
                       "cannot read image '" + image + "' at " + file.string());
    const SiftFeatures f = ExtractSift(gray, options());
    const k::LocalFeatureInfos infos = Infos(options());
    k::WriteImageLocalFeatures(
        ctx.output_dir(), options().type, image, infos,
        k::FeatureArray::From(k::DType::kFloat32, 4, f.keypoints),
        infos.descriptors.dtype == k::DType::kUint8
            ? k::FeatureArray::From(k::DType::kUint8, 128, DescriptorsToUint8(f.descriptors))
            : k::FeatureArray::From(k::DType::kFloat32, 128, f.descriptors));
  }

  void Finalize(RunContext& ctx) override {
    k::WriteLocalFeatureSetInfos(ctx.output_dir(), options().type, Infos(options()));
  }
};

// ---------------------------------------------------------------- import

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
    if (!type.empty() && !ValidTypeName(type)) {
      *why = "parameter 'type': '" + type + "' is not a folder name";
      return false;
    }
    return true;
  }
};

class ImportStage : public Stage<ImportOptions> {
 public:
  static StageMeta Meta() {
    return {"features", "import",
            "Imports an existing kapture keypoints + descriptors folder (validated copy)",
            {},
            {{"features", "kapture.local_features", "the imported keypoints + descriptors"}}};
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
    if (!ValidTypeName(type)) throw InputError(src.string(), 0, "type", "'" + type + "' is not a folder name");
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

}  // namespace locforge::sift

LOCFORGE_PLUGIN("features_sift", "1.1.0", "OpenCV SIFT local features and feature import",
                locforge::sift::SiftStage, locforge::sift::ImportStage)

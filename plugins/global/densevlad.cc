// global/densevlad: one DenseVLAD descriptor per image (library: densevlad/).
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
    StageMeta meta = {"global", "densevlad", "DenseVLAD global descriptor per image (float32 .gfeat)",
            {{"images", "kapture.dataset", "images to describe"},
             {"vocabulary", "densevlad.vocabulary", "from global/densevlad_vocabulary"}},
            {{"features", "kapture.global_features", "one .gfeat per image"}}};
    meta.version = "2.1.0";  // 2.0.0: vl_dsift-style dense SIFT (descriptors differ from 1.0.0); 2.1.0: a damaged image fails
    return meta;
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

}  // namespace

LOCFORGE_REGISTER_STAGE(DenseVladStage)

}  // namespace locforge::global

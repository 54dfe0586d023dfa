// global/netvlad, global/apgem, global/delg: one stage template over the
// learned global descriptors of learned/ (ONNX models through OpenCV dnn);
// netvlad.cc, apgem.cc and delg.cc export one instance each.
#ifndef LOCFORGE_PLUGINS_GLOBAL_LEARNED_STAGE_H_
#define LOCFORGE_PLUGINS_GLOBAL_LEARNED_STAGE_H_

#include <cstdio>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>

#include "global_descriptor.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "onnx_net.h"
#include "per_image_stage.h"

namespace locforge::learned {

namespace k = locforge::kapture;

template <GlobalModel kModel>
struct ModelOptions : GlobalOptions {
  ModelOptions() : GlobalOptions(GlobalOptions::Defaults(kModel)) {}
  static void Declare(ParamSchema<ModelOptions>& s) { DeclareGlobalOptions(s); }
};

template <GlobalModel kModel>
class GlobalStage : public PerImageStage<ModelOptions<kModel>> {
 public:
  using Base = PerImageStage<ModelOptions<kModel>>;
  static StageMeta Meta() {
    static const char* kNames[] = {"netvlad", "apgem", "delg"};
    static const char* kDocs[] = {
        "NetVLAD global descriptor per image (ONNX model, OpenCV dnn; float32 .gfeat)",
        "AP-GeM global descriptor per image (GeM pooling + learnt whitening; ONNX, OpenCV dnn)",
        "DELG global descriptor per image (the global head; ONNX, OpenCV dnn; multi-scale)"};
    const int m = static_cast<int>(kModel);
    StageMeta meta = {"global", kNames[m], kDocs[m],
            {kImagesPort},
            {{"features", "kapture.global_features", "one .gfeat per image"}}};
    meta.version = "1.2.0";  // 1.2.0: a damaged image fails its item
    return meta;
  }
  using Base::Base;

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const GlobalDescriptor g = ExtractGlobal(this->Image(ctx, image), this->options(), Pca());
    char line[160];
    std::snprintf(line, sizeof line, "%zu dims, network %.3f s", g.values.size(), g.network_seconds);
    ctx.Debug(image + ": " + line);
    k::WriteImageFeatures(ctx.output_dir(), this->options().type, Info(static_cast<int64_t>(g.values.size())),
                          image, k::FeatureArray::From(k::DType::kFloat32, g.values.size(), g.values));
    std::lock_guard<std::mutex> lock(mutex_);
    dims_ = static_cast<int64_t>(g.values.size());
  }
  void Finalize(RunContext& ctx) override {
    if (dims_ == 0) {  // a resumed run: the dimension from a probe image
      const cv::Mat probe(64, 64, CV_8UC3, cv::Scalar(128, 128, 128));
      dims_ = static_cast<int64_t>(ExtractGlobal(probe, this->options(), Pca()).values.size());
    }
    k::WriteFeatureSetInfo(ctx.output_dir(), this->options().type, Info(dims_));
  }

 private:
  k::FeatureInfo Info(int64_t dims) const {
    k::FeatureInfo info;
    info.kind = k::FeatureKind::kGlobalFeatures;
    info.name = Meta().name;
    info.dtype_name = "float32";
    info.dtype = k::DType::kFloat32;
    info.dsize = dims;
    info.metric_type = "L2";
    return info;
  }
  const PcaWhitening* Pca() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (this->options().pca_file.empty()) return nullptr;
    if (!pca_)
      pca_ = std::make_unique<PcaWhitening>(
          PcaWhitening::Read(this->options().pca_file, this->options().pca_dims));
    return pca_.get();
  }
  std::mutex mutex_;
  std::unique_ptr<PcaWhitening> pca_;
  int64_t dims_ = 0;
};

}  // namespace locforge::learned

#endif  // LOCFORGE_PLUGINS_GLOBAL_LEARNED_STAGE_H_

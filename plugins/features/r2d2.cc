// Stages (per image): features/r2d2, features/d2net (keypoints + descriptors
// in kapture), global/netvlad, global/apgem, global/delg (one .gfeat each).
#include <cstdio>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "d2net.h"
#include "global_descriptor.h"
#include "r2d2.h"

namespace locforge::learned {

namespace {

namespace k = locforge::kapture;

// The image of a records_camera.txt entry as 8-bit RGB; InputError naming it
// when unreadable.
cv::Mat ReadRgb(const fs::path& dataset, const std::string& image) {
  const fs::path file = k::Kapture(dataset).ExistingRecordDataPath(image, k::layout::RecordsFile("camera"));
  const cv::Mat bgr = cv::imread(file.string(), cv::IMREAD_COLOR);
  if (bgr.empty())
    throw InputError(k::layout::RecordsFile("camera"), 0, "image_path",
                     "cannot read image '" + image + "' at " + file.string());
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

// keypoints "r2d2" float32 x 3 (x, y in the SDK convention, see r2d2.h;
// scale), descriptors float32 x 128, L2.
k::LocalFeatureInfos R2d2Infos(const R2d2Options& o) {
  return k::MakeLocalFeatureInfos(o.type, "r2d2", 3, k::DType::kFloat32, 128);
}

class R2d2Stage : public PerItemStage<R2d2Options> {
 public:
  static StageMeta Meta() {
    return {"features", "r2d2", "R2D2 keypoints and descriptors per image (ONNX model, OpenCV dnn)",
            {{"images", "kapture.dataset", "images to describe (records_camera.txt)"}},
            {{"features", "kapture.local_features", "keypoints + descriptors of one type"}}};
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override {
    return k::Kapture(ctx.Input("images")).CameraImages();
  }

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const R2d2Features f = ExtractR2d2(ReadRgb(ctx.Input("images"), image), options());
    char line[160];
    std::snprintf(line, sizeof line, "%d keypoints, network %.3f s over %d scales", f.count(),
                  f.network_seconds, f.scales);
    ctx.Debug(image + ": " + line);
    k::WriteImageLocalFeatures(ctx.output_dir(), options().type, image, R2d2Infos(options()),
                               k::FeatureArray::From(k::DType::kFloat32, 3, f.keypoints),
                               k::FeatureArray::From(k::DType::kFloat32, 128, f.descriptors));
  }

  void Finalize(RunContext& ctx) override {
    k::WriteLocalFeatureSetInfos(ctx.output_dir(), options().type, R2d2Infos(options()));
  }
};

// ------------------------------------------------------------ features/d2net

// keypoints "d2net" float32 x 3 (x, y, 1 / scale), descriptors float32 x
// channels, L2.
k::LocalFeatureInfos D2netInfos(const D2netOptions& o, int64_t channels) {
  return k::MakeLocalFeatureInfos(o.type, "d2net", 3, k::DType::kFloat32, channels);
}

class D2netStage : public PerItemStage<D2netOptions> {
 public:
  static StageMeta Meta() {
    return {"features", "d2net",
            "D2-Net dense features, hard detection and descriptors per image (ONNX model, OpenCV dnn)",
            {{"images", "kapture.dataset", "images to describe (records_camera.txt)"}},
            {{"features", "kapture.local_features", "keypoints (x, y, 1/scale) + descriptors"}}};
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override {
    return k::Kapture(ctx.Input("images")).CameraImages();
  }
  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const D2netFeatures f = ExtractD2net(ReadRgb(ctx.Input("images"), image), options());
    char line[160];
    std::snprintf(line, sizeof line, "%d keypoints, network %.3f s over %d levels", f.count(),
                  f.network_seconds, f.levels);
    ctx.Debug(image + ": " + line);
    const int channels = f.channels > 0 ? f.channels : ProbeChannels();
    k::WriteImageLocalFeatures(ctx.output_dir(), options().type, image,
                               D2netInfos(options(), channels),
                               k::FeatureArray::From(k::DType::kFloat32, 3, f.keypoints),
                               k::FeatureArray::From(k::DType::kFloat32, channels, f.descriptors));
    std::lock_guard<std::mutex> lock(mutex_);
    channels_ = channels;
  }
  void Finalize(RunContext& ctx) override {
    if (channels_ == 0) channels_ = ProbeChannels();
    k::WriteLocalFeatureSetInfos(ctx.output_dir(), options().type, D2netInfos(options(), channels_));
  }

 private:
  // Descriptor size from the model on a small image (when no image of this
  // run gave it, e.g. a resumed run).
  int ProbeChannels() const {
    const cv::Mat probe(64, 64, CV_8UC3, cv::Scalar(128, 128, 128));
    D2netOptions o = options();
    o.scales = {1.0};
    return ExtractD2net(probe, o).channels;
  }
  std::mutex mutex_;
  int channels_ = 0;
};

// ------------------------------------------------- global/netvlad|apgem|delg

template <GlobalModel kModel>
struct ModelOptions : GlobalOptions {
  ModelOptions() : GlobalOptions(GlobalOptions::Defaults(kModel)) {}
  static void Declare(ParamSchema<ModelOptions>& s) { DeclareGlobalOptions(s); }
};

template <GlobalModel kModel>
class GlobalStage : public PerItemStage<ModelOptions<kModel>> {
 public:
  using Base = PerItemStage<ModelOptions<kModel>>;
  static StageMeta Meta() {
    static const char* kNames[] = {"netvlad", "apgem", "delg"};
    static const char* kDocs[] = {
        "NetVLAD global descriptor per image (ONNX model, OpenCV dnn; float32 .gfeat)",
        "AP-GeM global descriptor per image (GeM pooling + learnt whitening; ONNX, OpenCV dnn)",
        "DELG global descriptor per image (the global head; ONNX, OpenCV dnn; multi-scale)"};
    const int m = static_cast<int>(kModel);
    return {"global", kNames[m], kDocs[m],
            {{"images", "kapture.dataset", "images to describe (records_camera.txt)"}},
            {{"features", "kapture.global_features", "one .gfeat per image"}}};
  }
  using Base::Base;

  std::vector<std::string> ListItems(RunContext& ctx) override {
    return k::Kapture(ctx.Input("images")).CameraImages();
  }
  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const GlobalDescriptor g = ExtractGlobal(ReadRgb(ctx.Input("images"), image), this->options(), Pca());
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

}  // namespace

}  // namespace locforge::learned

LOCFORGE_PLUGIN("learned", "1.1.0",
                "Learned features with OpenCV dnn: R2D2, D2-Net; NetVLAD, AP-GeM, DELG global descriptors",
                locforge::learned::R2d2Stage, locforge::learned::D2netStage,
                locforge::learned::GlobalStage<locforge::learned::GlobalModel::kNetVlad>,
                locforge::learned::GlobalStage<locforge::learned::GlobalModel::kApGem>,
                locforge::learned::GlobalStage<locforge::learned::GlobalModel::kDelg>)

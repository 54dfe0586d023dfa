// features/d2net: D2-Net dense features per image (ONNX model through
// OpenCV dnn; library: d2net/).
#include <cstdio>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>

#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "onnx_net.h"
#include "per_image_stage.h"
#include "d2net.h"

namespace locforge::features {

using namespace ::locforge::learned;  // the library this stage wires

namespace {

namespace k = locforge::kapture;

// keypoints "d2net" float32 x 3 (x, y, 1 / scale), descriptors float32 x
// channels, L2.
k::LocalFeatureInfos D2netInfos(const D2netOptions& o, int64_t channels) {
  return k::MakeLocalFeatureInfos(o.type, "d2net", 3, k::DType::kFloat32, channels);
}

class D2netStage : public PerImageStage<D2netOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"features", "d2net",
            "D2-Net dense features, hard detection and descriptors per image (ONNX model, OpenCV dnn)",
            {kImagesPort},
            {{"features", "kapture.local_features", "keypoints (x, y, 1/scale) + descriptors"}}};
    meta.version = "1.2.0";  // 1.2.0: a damaged image fails its item
    return meta;
  }
  using PerImageStage::PerImageStage;

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const D2netFeatures f = ExtractD2net(Image(ctx, image), options());
    char line[160];
    std::snprintf(line, sizeof line, "%d keypoints, network %.3f s over %d levels", f.count(),
                  f.network_seconds, f.levels);
    const int channels = f.channels > 0 ? f.channels : ProbeChannels();
    WriteFloatFeatures(ctx, image, line, options().type, D2netInfos(options(), channels), 3, f.keypoints, channels,
                       f.descriptors);
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

}  // namespace

LOCFORGE_REGISTER_STAGE(D2netStage)

}  // namespace locforge::features

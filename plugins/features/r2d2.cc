// features/r2d2: R2D2 keypoints and descriptors per image (ONNX model through
// OpenCV dnn; library: r2d2/).
#include <cstdio>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>

#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "onnx_net.h"
#include "per_image_stage.h"
#include "r2d2.h"

namespace locforge::features {

using namespace ::locforge::learned;  // the library this stage wires

namespace {

namespace k = locforge::kapture;

// keypoints "r2d2" float32 x 3 (x, y in the SDK convention, see r2d2.h;
// scale), descriptors float32 x 128, L2.
k::LocalFeatureInfos R2d2Infos(const R2d2Options& o) {
  return k::MakeLocalFeatureInfos(o.type, "r2d2", 3, k::DType::kFloat32, 128);
}

class R2d2Stage : public PerImageStage<R2d2Options> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"features", "r2d2", "R2D2 keypoints and descriptors per image (ONNX model, OpenCV dnn)",
            {kImagesPort},
            {{"features", "kapture.local_features", "keypoints + descriptors of one type"}}};
    meta.version = "1.2.0";  // 1.2.0: a damaged image fails its item
    return meta;
  }
  using PerImageStage::PerImageStage;

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const R2d2Features f = ExtractR2d2(Image(ctx, image), options());
    char line[160];
    std::snprintf(line, sizeof line, "%d keypoints, network %.3f s over %d scales", f.count(),
                  f.network_seconds, f.scales);
    WriteFloatFeatures(ctx, image, line, options().type, R2d2Infos(options()), 3, f.keypoints, 128, f.descriptors);
  }

  void Finalize(RunContext& ctx) override {
    k::WriteLocalFeatureSetInfos(ctx.output_dir(), options().type, R2d2Infos(options()));
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(R2d2Stage)

}  // namespace locforge::features

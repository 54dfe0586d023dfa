// features/xfeat: XFeat keypoints and descriptors per image (the authors'
// weights as a free-size ONNX model, OpenCV dnn; library: xfeat/).
#include <cstdio>

#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "per_image_stage.h"
#include "xfeat.h"

namespace locforge::features {

using namespace ::locforge::learned;  // the library this stage wires

namespace {

namespace k = locforge::kapture;

// keypoints "xfeat" float32 x 2 (x, y in the SDK convention, see xfeat.h),
// descriptors float32 x 64, L2.
k::LocalFeatureInfos XfeatInfos(const XfeatOptions& o) {
  return k::MakeLocalFeatureInfos(o.type, "xfeat", 2, k::DType::kFloat32, 64);
}

class XfeatStage : public PerImageStage<XfeatOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"features", "xfeat",
                      "XFeat keypoints and 64-D descriptors per image (CVPR 2024; the authors' weights, "
                      "free-size ONNX model, OpenCV dnn; the authors' detectAndCompute)",
                      {kImagesPort},
                      {{"features", "kapture.local_features", "keypoints + descriptors of one type"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using PerImageStage::PerImageStage;

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const XfeatFeatures f = ExtractXfeat(Image(ctx, image), options());
    char line[160];
    std::snprintf(line, sizeof line, "%d keypoints, network %.3f s at %dx%d", f.count(),
                  f.network_seconds, f.network_width, f.network_height);
    WriteFloatFeatures(ctx, image, line, options().type, XfeatInfos(options()), 2, f.keypoints, 64, f.descriptors);
  }

  void Finalize(RunContext& ctx) override {
    k::WriteLocalFeatureSetInfos(ctx.output_dir(), options().type, XfeatInfos(options()));
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(XfeatStage)

}  // namespace locforge::features

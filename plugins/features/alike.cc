// features/alike: ALIKE keypoints and descriptors per image (the authors'
// weights, sizes t/s/n/l, as free-size ONNX models, OpenCV dnn; library: alike/).
#include <cstdio>

#include "alike.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "per_image_stage.h"

namespace locforge::features {

using namespace ::locforge::learned;  // the library this stage wires

namespace {

namespace k = locforge::kapture;

// keypoints "alike" float32 x 2 (x, y in the SDK convention, see alike.h),
// descriptors float32 x dim (64, 96, 128, 128 for t, s, n, l), L2.
k::LocalFeatureInfos AlikeInfos(const AlikeOptions& o, int dim) {
  return k::MakeLocalFeatureInfos(o.type, "alike", 2, k::DType::kFloat32, dim);
}

class AlikeStage : public PerImageStage<AlikeOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"features", "alike",
                      "ALIKE keypoints and descriptors per image (IEEE TMM 2022; the authors' t/s/n/l "
                      "weights, free-size ONNX model, OpenCV dnn; NMS + soft-argmax refinement)",
                      {kImagesPort},
                      {{"features", "kapture.local_features", "keypoints + descriptors of one type"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using PerImageStage::PerImageStage;

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const AlikeFeatures f = ExtractAlike(Image(ctx, image), options());
    char line[160];
    std::snprintf(line, sizeof line, "%d keypoints, network %.3f s", f.count(), f.network_seconds);
    WriteFloatFeatures(ctx, image, line, options().type, AlikeInfos(options(), f.dim), 2, f.keypoints, f.dim,
                       f.descriptors);
  }

  void Finalize(RunContext& ctx) override {
    k::WriteLocalFeatureSetInfos(ctx.output_dir(), options().type,
                                 AlikeInfos(options(), AlikeDescriptorDim(options().model)));
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(AlikeStage)

}  // namespace locforge::features

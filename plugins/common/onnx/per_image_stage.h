// The base of the learned per-image stages (features/r2d2|d2net|xfeat|alike,
// global/netvlad|apgem|delg): one item per image of records_camera.txt of
// the `images` input, read as 8-bit RGB.
#ifndef LOCFORGE_PLUGINS_COMMON_ONNX_PER_IMAGE_STAGE_H_
#define LOCFORGE_PLUGINS_COMMON_ONNX_PER_IMAGE_STAGE_H_

#include <string>
#include <vector>

#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "onnx_net.h"

namespace locforge::learned {

// The `images` input port of these stages.
inline const PortMeta kImagesPort{"images", "kapture.dataset", "images to describe (records_camera.txt)"};

template <typename Options>
class PerImageStage : public PerItemStage<Options> {
 public:
  using PerItemStage<Options>::PerItemStage;
  std::vector<std::string> ListItems(RunContext& ctx) override {
    return kapture::Kapture(ctx.Input("images")).CameraImages();
  }

 protected:
  static cv::Mat Image(RunContext& ctx, const std::string& image) {
    return ReadRgb(ctx.Input("images"), image);
  }
  // A local-feature stage's output for one image: a debug line saying what the
  // network did, then float32 keypoints (keypoint_width values each) and
  // descriptors (dim values each) of feature type `type`.
  static void WriteFloatFeatures(RunContext& ctx, const std::string& image, const std::string& network_log,
                                 const std::string& type, const kapture::LocalFeatureInfos& infos,
                                 int keypoint_width, const std::vector<float>& keypoints, int64_t dim,
                                 const std::vector<float>& descriptors) {
    ctx.Debug(image + ": " + network_log);
    kapture::WriteImageLocalFeatures(ctx.output_dir(), type, image, infos,
                                     kapture::FeatureArray::From(kapture::DType::kFloat32, keypoint_width, keypoints),
                                     kapture::FeatureArray::From(kapture::DType::kFloat32, dim, descriptors));
  }
};

}  // namespace locforge::learned

#endif  // LOCFORGE_PLUGINS_COMMON_ONNX_PER_IMAGE_STAGE_H_

// The base of the learned per-image stages (features/r2d2, features/d2net,
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
};

}  // namespace locforge::learned

#endif  // LOCFORGE_PLUGINS_COMMON_ONNX_PER_IMAGE_STAGE_H_

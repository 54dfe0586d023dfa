// features/sift: OpenCV SIFT (or RootSIFT) keypoints and descriptors per
// image (library: sift/).
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "image_read.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "sift.h"

namespace locforge::features {

using namespace ::locforge::sift;  // the library this stage wires

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


class SiftStage : public PerItemStage<SiftOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"features", "sift", "OpenCV SIFT keypoints and (Root)SIFT descriptors per image",
            {{"images", "kapture.dataset", "images to describe (records_camera.txt)"}},
            {{"features", "kapture.local_features", "keypoints + descriptors of one type"}}};
    meta.version = "1.3.0";  // 1.2.0: a damaged image fails its item; 1.3.0: cap_order
    return meta;
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override {
    return k::Kapture(ctx.Input("images")).CameraImages();
  }

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const cv::Mat gray = image_io::ReadCameraImage(ctx.Input("images"), image, cv::IMREAD_GRAYSCALE);
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

}  // namespace

LOCFORGE_REGISTER_STAGE(SiftStage)

}  // namespace locforge::features

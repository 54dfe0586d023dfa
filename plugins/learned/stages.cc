// Stage features/r2d2 (per image): R2D2 keypoints + descriptors in kapture.
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "r2d2.h"

namespace locforge::learned {

namespace {

namespace k = locforge::kapture;

k::FeatureInfo KeypointsInfo() {
  k::FeatureInfo info;
  info.kind = k::FeatureKind::kKeypoints;
  info.name = "r2d2";
  info.dtype_name = "float32";
  info.dtype = k::DType::kFloat32;
  info.dsize = 3;  // x, y (SDK convention, see r2d2.h), scale
  return info;
}

k::FeatureInfo DescriptorsInfo(const R2d2Options& o) {
  k::FeatureInfo info;
  info.kind = k::FeatureKind::kDescriptors;
  info.name = "r2d2";
  info.dtype_name = "float32";
  info.dtype = k::DType::kFloat32;
  info.dsize = 128;
  info.keypoints_type = o.type;
  info.metric_type = "L2";
  return info;
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
    const fs::path root = ctx.Input("images");
    const fs::path file = SafeJoin(root / k::layout::kRecordsData, image, "records_camera.txt");
    const cv::Mat bgr = cv::imread(file.string(), cv::IMREAD_COLOR);
    if (bgr.empty())
      throw InputError(k::layout::RecordsFile("camera"), 0, "image_path",
                       "cannot read image '" + image + "' at " + file.string());
    cv::Mat rgb;
    cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
    const R2d2Features f = ExtractR2d2(rgb, options());
    char line[160];
    std::snprintf(line, sizeof line, "%d keypoints, network %.3f s over %d scales", f.count(),
                  f.network_seconds, f.scales);
    ctx.Debug(image + ": " + line);
    const fs::path out = ctx.output_dir();
    k::WriteImageFeatures(out, options().type, KeypointsInfo(), image,
                          k::FeatureArray::From(k::DType::kFloat32, 3, f.keypoints));
    k::WriteImageFeatures(out, options().type, DescriptorsInfo(options()), image,
                          k::FeatureArray::From(k::DType::kFloat32, 128, f.descriptors));
  }

  void Finalize(RunContext& ctx) override {
    k::WriteFeatureSetInfo(ctx.output_dir(), options().type, KeypointsInfo());
    k::WriteFeatureSetInfo(ctx.output_dir(), options().type, DescriptorsInfo(options()));
  }
};

}  // namespace

}  // namespace locforge::learned

LOCFORGE_PLUGIN("learned", "1.0.0", "Learned local features (R2D2 ONNX models with OpenCV dnn)",
                locforge::learned::R2d2Stage)

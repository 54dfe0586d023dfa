// verify/two_view: RANSAC two-view geometry per matched pair (OpenCV USAC).
#include "verify_stage.h"

namespace locforge::verify {

using namespace ::locforge::matching;  // the library this stage wires

namespace {

struct TwoViewStageOptions {
  double max_error_px = 4.0;      // RANSAC inlier threshold, pixels.
  double confidence = 0.9999;
  int max_iterations = 10000;
  std::string method = "magsac";  // OpenCV USAC_MAGSAC, or "usac" for USAC_DEFAULT.
  std::string geometry = "auto";  // essential when both cameras are known.
  int min_inliers = 15;           // Pairs with fewer inliers get no file.
  static void Declare(ParamSchema<TwoViewStageOptions>& s) {
    s.Add("max_error_px", &TwoViewStageOptions::max_error_px, "RANSAC inlier threshold (pixels)")
        .Range(0.1, 100);
    s.Add("confidence", &TwoViewStageOptions::confidence, "RANSAC confidence").Range(0.5, 0.999999);
    s.Add("max_iterations", &TwoViewStageOptions::max_iterations, "RANSAC iterations cap")
        .Range(10, 1000000);
    s.Add("method", &TwoViewStageOptions::method,
          "OpenCV USAC flavour: magsac (USAC_MAGSAC) or usac (USAC_DEFAULT)")
        .Choices({"magsac", "usac"});
    s.Add("geometry", &TwoViewStageOptions::geometry,
          "auto: essential when both images have intrinsics, else fundamental")
        .Choices({"auto", "essential", "fundamental"});
    s.Add("min_inliers", &TwoViewStageOptions::min_inliers, "pairs with fewer inliers get no file")
        .Min(0);
  }
  TwoViewOptions Ransac() const {
    TwoViewOptions o;
    o.max_error_px = max_error_px;
    o.confidence = confidence;
    o.max_iterations = max_iterations;
    o.method = method;
    return o;
  }
};

class TwoViewStage : public VerifyStage<TwoViewStageOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = VerifyMeta("two_view",
                      "RANSAC two-view geometry (OpenCV USAC essential/fundamental); keeps inlier matches",
                      "cameras of the map images (for essential matrices)", LF_PORT_OPTIONAL,
                      "cameras of the query images");
    meta.version = "1.0.0";
    return meta;
  }
  using VerifyStage::VerifyStage;

 protected:
  std::vector<int> Keep(const std::string& a, const std::string& b, const ImageGeometry::Entry* ea,
                        const ImageGeometry::Entry* eb, const std::vector<Eigen::Vector2d>& pa,
                        const std::vector<Eigen::Vector2d>& pb) override {
    const bool known = ea && eb && ea->has_camera && eb->has_camera;
    const std::string& mode = options().geometry;
    if (mode == "essential" && !known)
      throw InputError("images", 0, "camera", "no intrinsics for '" + (ea && ea->has_camera ? b : a) +
                                                  "' (geometry: essential)");
    const bool essential = mode == "essential" || (mode == "auto" && known);
    return VerifyTwoView(pa, pb, essential ? &ea->camera : nullptr, essential ? &eb->camera : nullptr,
                         options().Ransac())
        .inliers;
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(TwoViewStage)

}  // namespace locforge::verify

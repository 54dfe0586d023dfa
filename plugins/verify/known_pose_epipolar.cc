// verify/known_pose_epipolar: the matches consistent with the epipolar
// geometry of the two known poses.
#include "verify_stage.h"

namespace locforge::verify {

using namespace ::locforge::matching;  // the library this stage wires

namespace {

struct EpipolarOptions {
  double max_error_px = 4.0;
  int min_inliers = 1;
  bool keep_unknown = true;
  static void Declare(ParamSchema<EpipolarOptions>& s) {
    s.Add("max_error_px", &EpipolarOptions::max_error_px,
          "Sampson distance to the epipolar geometry of the known poses (pixels)").Range(0.01, 1000);
    s.Add("min_inliers", &EpipolarOptions::min_inliers, "pairs with fewer kept matches get no file").Min(0);
    s.Add("keep_unknown", &EpipolarOptions::keep_unknown,
          "pairs lacking a pose or camera keep all matches (else they are dropped)");
  }
};

class KnownPoseEpipolarStage : public VerifyStage<EpipolarOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = VerifyMeta("known_pose_epipolar",
                      "Keeps matches consistent with the epipolar geometry of the two known poses",
                      "cameras and poses of the map images", 0,
                      "cameras and poses of the query images");
    meta.version = "1.0.0";
    return meta;
  }
  using VerifyStage::VerifyStage;

 protected:
  std::vector<int> Keep(const std::string&, const std::string&, const ImageGeometry::Entry* ea,
                        const ImageGeometry::Entry* eb, const std::vector<Eigen::Vector2d>& pa,
                        const std::vector<Eigen::Vector2d>& pb) override {
    std::vector<int> keep;
    if (!ea || !eb || !ea->has_camera || !eb->has_camera || !ea->pose || !eb->pose) {
      if (options().keep_unknown)
        for (int i = 0; i < static_cast<int>(pa.size()); ++i) keep.push_back(i);
      return keep;
    }
    const auto errors = EpipolarErrorsPx(pa, pb, ea->camera, eb->camera, *ea->pose, *eb->pose);
    for (int i = 0; i < static_cast<int>(errors.size()); ++i)
      if (errors[i] <= options().max_error_px) keep.push_back(i);
    return keep;
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(KnownPoseEpipolarStage)

}  // namespace locforge::verify

// localizer/posenet: absolute pose regression per query image (ONNX model run
// by OpenCV dnn; contract in scene_regression/README.md).
#include <chrono>

#include "regression_stage.h"
#include "scene_regression.h"

namespace locforge::localizer {

using namespace ::locforge::regression;  // the library this stage wires
namespace {

struct PoseNetOptions : InputOptions {
  std::string model;                         // .onnx file (required).
  std::string position_output = "position";  // 1x3: camera centre in the world, metres.
  std::string orientation_output = "orientation";  // 1x4: R_world_camera as (w, x, y, z).

  static void Declare(ParamSchema<PoseNetOptions>& s) {
    s.Add("model", &PoseNetOptions::model, "the network (.onnx file, contract in plugins/localizer/scene_regression/README.md)")
        .Path().Required();
    DeclareInputOptions(s);
    s.Add("position_output", &PoseNetOptions::position_output,
          "output tensor: camera centre in the world (1x3, metres)");
    s.Add("orientation_output", &PoseNetOptions::orientation_output,
          "output tensor: rotation world_from_camera as a quaternion (w, x, y, z), any norm (1x4)");
  }
  bool Check(std::string* why) const {
    if (position_output.empty() || orientation_output.empty())
      return *why = "position_output/orientation_output: empty tensor name", false;
    return InputOptions::Check(why);
  }
};

class PoseNetLocalizer : public RegressionStage<PoseNetOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"localizer", "posenet",
                      "absolute pose regression (PoseNet): one network pass per query image gives the "
                      "camera centre and rotation; non-finite outputs are failures, never guessed",
                      {kQueryPort},
                      {kTrajectoriesPort}};
    meta.version = "1.1.0";  // 1.1.0: a damaged image fails its item
    return meta;
  }
  using RegressionStage::RegressionStage;

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    Camera camera;
    const cv::Mat rgb = QueryImage(ctx, image, &camera);
    const auto start = std::chrono::steady_clock::now();
    cv::dnn::Net& net = learned::ThreadNet(options().model);
    net.setInput(learned::InputBlob(rgb, options()), options().input);
    std::vector<cv::Mat> outs;
    net.forward(outs, std::vector<cv::String>{options().position_output, options().orientation_output});
    if (outs[0].total() != 3 || outs[1].total() != 4)
      throw InputError(options().model, 0, "outputs",
                       "expected 3 position and 4 orientation values, got " + std::to_string(outs[0].total()) +
                           " and " + std::to_string(outs[1].total()));
    localization::QueryOutcome o;
    o.success = PoseFromRegression(outs[0].ptr<float>(), outs[1].ptr<float>(), &o.device_from_world, &o.failure);
    o.stats = {learned::SecondsSince(start)};
    localization::WriteQueryResult(ctx.output_dir(), image, o);
  }

 protected:
  std::vector<std::string> StatNames() const override { return {"network_seconds"}; }
};

}  // namespace
LOCFORGE_REGISTER_STAGE(PoseNetLocalizer)

}  // namespace locforge::localizer

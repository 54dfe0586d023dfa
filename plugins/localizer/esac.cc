// localizer/esac: scene-coordinate regression with a gating network over
// experts (ESAC), 2D-3D hypotheses through localizer/pnp's LO-RANSAC P3P +
// refinement (scene_regression.h; contract in scene_regression/README.md).
#include <chrono>
#include <cstdio>

#include "regression_stage.h"
#include "scene_regression.h"

namespace locforge::localizer {

using namespace ::locforge::regression;  // the library this stage wires
namespace {

namespace lz = locforge::localization;

struct EsacOptions : InputOptions {
  std::string model_dir;       // gating.onnx + expert_000.onnx ... (required).
  int experts = 0;             // Experts expected in model_dir; 0: as many as found.
  std::string gating_output = "logits";          // 1xE gating logits.
  std::string expert_output = "coordinates";     // 1x3xhxw scene coordinates, metres.
  int hypotheses = 256;        // RANSAC hypotheses over all experts (the paper's M).
  double max_error_px = 10.0;  // Inlier threshold, pixels (the paper's tau).
  int min_inliers = 10;        // Fewer inliers: the query fails.
  double cauchy_scale_px = 1.0;  // Cauchy loss scale of the refinement.
  int64_t seed = 0;              // RANSAC seed (deterministic).

  static void Declare(ParamSchema<EsacOptions>& s) {
    s.Add("model_dir", &EsacOptions::model_dir,
          "folder of gating.onnx (absent with one expert) and expert_000.onnx, expert_001.onnx, ...")
        .Path().Required();
    s.Add("experts", &EsacOptions::experts, "experts expected in model_dir (0: as many as found)").Range(0, 1000);
    DeclareInputOptions(s);
    s.Add("gating_output", &EsacOptions::gating_output, "gating output tensor (1xE logits)");
    s.Add("expert_output", &EsacOptions::expert_output, "expert output tensor (1x3xhxw world coordinates, metres)");
    s.Add("hypotheses", &EsacOptions::hypotheses,
          "RANSAC hypotheses shared by the experts in proportion to the gating probabilities").Range(1, 100000);
    s.Add("max_error_px", &EsacOptions::max_error_px, "inlier threshold, pixels").Min(0.01);
    s.Add("min_inliers", &EsacOptions::min_inliers, "fewer inliers: the query fails").Min(4);
    s.Add("cauchy_scale_px", &EsacOptions::cauchy_scale_px, "Cauchy loss scale of the refinement, pixels").Min(1e-3);
    s.Add("seed", &EsacOptions::seed, "RANSAC random seed").Min(0);
  }
  bool Check(std::string* why) const {
    return InputOptions::Check(why);
  }
};

std::string ExpertFile(const std::string& dir, int e) {
  char name[32];
  std::snprintf(name, sizeof name, "expert_%03d.onnx", e);
  return (fs::path(dir) / name).string();
}

class EsacLocalizer : public RegressionStage<EsacOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"localizer", "esac",
                      "scene-coordinate regression with expert selection (ESAC): gating network, "
                      "experts' 2D-3D hypotheses split by the gating probabilities, LO-RANSAC P3P + "
                      "refinement of localizer/pnp; a query without enough inliers fails, never guessed",
                      {kQueryPort},
                      {kTrajectoriesPort}};
    meta.version = "1.1.0";  // 1.1.0: a damaged image fails its item
    return meta;
  }
  using RegressionStage::RegressionStage;

  std::vector<std::string> ListItems(RunContext& ctx) override {
    CountExperts();
    return RegressionStage::ListItems(ctx);
  }

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    CountExperts();
    Camera camera;
    const cv::Mat rgb = QueryImage(ctx, image, &camera);
    const auto start = std::chrono::steady_clock::now();
    const cv::Mat blob = learned::InputBlob(rgb, options());
    std::vector<double> p = {1.0};
    if (experts_ > 1) {
      cv::dnn::Net& gating = learned::ThreadNet((fs::path(options().model_dir) / "gating.onnx").string());
      gating.setInput(blob, options().input);
      const cv::Mat logits = gating.forward(options().gating_output);
      if (static_cast<int>(logits.total()) != experts_)
        throw InputError(options().model_dir + "/gating.onnx", 0, "outputs",
                         std::to_string(logits.total()) + " logits for " + std::to_string(experts_) + " experts");
      p = Softmax(std::vector<float>(logits.ptr<float>(), logits.ptr<float>() + experts_));
    }
    const std::vector<int> budget = HypothesisBudget(p, options().hypotheses);
    std::vector<ExpertResult> results;
    for (int e = 0; e < experts_; ++e) {
      if (budget[e] == 0) continue;
      const std::string file = ExpertFile(options().model_dir, e);
      cv::dnn::Net& expert = learned::ThreadNet(file);
      expert.setInput(blob, options().input);
      const cv::Mat coordinates = expert.forward(options().expert_output);
      if (coordinates.dims != 4 || coordinates.size[0] != 1 || coordinates.size[1] != 3)
        throw InputError(file, 0, "outputs", "expected 1x3xhxw scene coordinates");
      ExpertResult r;
      r.expert = e;
      r.probability = p[e];
      r.hypotheses = budget[e];
      const std::vector<lz::Correspondence> cs = SceneCoordinateCorrespondences(coordinates, camera);
      r.correspondences = static_cast<int>(cs.size());
      lz::RansacOptions ransac;
      ransac.max_error_px = options().max_error_px;
      ransac.min_iterations = ransac.max_iterations = budget[e];
      ransac.min_inliers = options().min_inliers;
      ransac.refine.cauchy_scale_px = options().cauchy_scale_px;
      ransac.seed = static_cast<uint64_t>(options().seed) ^ std::hash<std::string>{}(image) ^ uint64_t(e);
      lz::RigCamera rc;
      rc.focal = 0.5 * (camera.fx() + camera.fy());
      r.pose = lz::EstimateAbsolutePose(cs, {rc}, ransac);
      results.push_back(std::move(r));
    }
    lz::QueryOutcome o;
    const int best = BestExpert(results);
    if (best >= 0) {
      o.success = true;
      o.device_from_world = results[best].pose.rig_from_world;
    } else {
      o.failure = "no expert reached min_inliers " + std::to_string(options().min_inliers);
      for (const ExpertResult& r : results)
        o.failure += "; expert " + std::to_string(r.expert) + ": " + r.pose.failure;
    }
    const ExpertResult* chosen = best >= 0 ? &results[best] : nullptr;
    const int top = static_cast<int>(std::max_element(p.begin(), p.end()) - p.begin());
    o.stats = {double(chosen ? chosen->expert : -1),
               chosen ? p[chosen->expert] : 0.0,
               double(top),
               double(results.size()),
               double(chosen ? chosen->correspondences : 0),
               double(chosen ? chosen->pose.num_inliers : 0),
               learned::SecondsSince(start)};
    localization::WriteQueryResult(ctx.output_dir(), image, o);
  }

 protected:
  std::vector<std::string> StatNames() const override {
    return {"expert", "gating_probability", "most_probable_expert", "experts_evaluated",
            "correspondences", "inliers", "seconds"};
  }

 private:
  // The experts of model_dir, checked against `experts` and the gate, once
  // (at run time: a graph validates before the models are trained).
  void CountExperts() {
    std::lock_guard<std::mutex> lock(experts_mutex_);
    if (experts_ > 0) return;
    const std::string& dir = options().model_dir;
    if (!fs::is_directory(dir)) throw InputError(dir, 0, "model_dir", "not a folder");
    int found = 0;
    while (fs::exists(ExpertFile(dir, found))) ++found;
    if (found == 0) throw InputError(dir, 0, "model_dir", "no expert_000.onnx");
    if (options().experts != 0 && options().experts != found)
      throw InputError(dir, 0, "experts", std::to_string(options().experts) + " experts expected, " +
                                              std::to_string(found) + " found (expert_000.onnx ...)");
    if (found > 1 && !fs::exists(fs::path(dir) / "gating.onnx"))
      throw InputError(dir, 0, "model_dir", std::to_string(found) + " experts but no gating.onnx");
    experts_ = found;
  }

  std::mutex experts_mutex_;
  int experts_ = 0;
};

}  // namespace
LOCFORGE_REGISTER_STAGE(EsacLocalizer)

}  // namespace locforge::localizer

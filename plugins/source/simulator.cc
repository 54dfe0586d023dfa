// Stage source/simulator (the simulator plugin, simulator/): a preset (tiny, small, large) plus overrides in,
// a kapture dataset with its ground truth out (layout in README.md).
#include <string>

#include "dataset.h"
#include "locforge/plugin.h"

namespace locforge::source {

using namespace ::locforge::sim;  // the library this stage wires

// A preset (a whole SimOptions) overlaid by the options the graph gives,
// declared once by SimOptions::Declare and bound in place.
struct SimulatorOptions {
  std::string preset = "small";
  double duration_scale = 1;  // multiplies every sequence's duration
  SimOptions sim = PresetOptions(preset);

  static void Declare(ParamSchema<SimulatorOptions>& s) {
    s.AddPreset("preset", &SimulatorOptions::preset, "Recording size: tiny (tests), small (demo), large (benchmark)",
                [](SimulatorOptions& o) { o.sim = PresetOptions(o.preset); })
        .Choices({"tiny", "small", "large"});
    s.Add("duration_scale", &SimulatorOptions::duration_scale, "Multiplies every sequence's duration")
        .Range(0.05, 100);
    s.AddGroup(&SimulatorOptions::sim);
  }

  SimOptions Resolved() const {
    SimOptions o = sim;
    o.mapping_duration_s *= duration_scale;
    o.query_duration_s *= duration_scale;
    return o;
  }

  bool Check(std::string* why) const { return Resolved().Check(why); }
};

class Simulator : public Stage<SimulatorOptions> {
 public:
  static StageMeta Meta() {
    return {"source",
            "simulator",
            "Simulates the mapping platform in a crowded indoor floor: kapture dataset with exact ground truth",
            {},
            {{"dataset", "kapture.dataset",
              "Mapping kapture (all sequences with layout=single); query kaptures in validation/ and test/, "
              "ground truth in truth/"}}};
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    Hooks hooks;
    hooks.log = [&](const std::string& m) { ctx.Info(m); };
    hooks.progress = [&](uint64_t done, uint64_t total) { ctx.Progress(done, total, "records"); };
    hooks.cancelled = [&] { return ctx.cancelled(); };
    const DatasetSummary s = GenerateDataset(options().Resolved(), ctx.output_dir(), ctx.threads(), hooks);
    ctx.Info("simulated " + std::to_string(s.sequences.size()) + " sequences: " + std::to_string(s.images) +
             " images, " + std::to_string(s.scans) + " LiDAR scans");
  }
};

LOCFORGE_REGISTER_STAGE(Simulator)

}  // namespace locforge::source

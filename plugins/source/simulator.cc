// Stage source/simulator (the simulator plugin, simulator/): a preset (tiny, small, large) plus overrides in,
// a kapture dataset with its ground truth out (layout in README.md).
#include <string>

#include "dataset.h"
#include "locforge/plugin.h"

namespace locforge::source {

using namespace ::locforge::sim;  // the library this stage wires

struct SimulatorOptions {
  std::string preset = "small";    // Size of the recording: tiny | small | large.
  int64_t seed = 0;                // Same seed, same dataset.
  double crowdedness = -1;         // People per 100 m^2 of floor; -1: the preset's.
  double query_crowdedness = -1;   // The same for the query sequences only; -1: as crowdedness.
  double scale = 0;                // Image resolution factor (1 = full sensor); 0: the preset's.
  double duration_scale = 1;       // Multiplies every sequence's duration.
  int mapping_sequences = 0;       // 0: the preset's.
  int validation_sequences = -1;   // -1: the preset's.
  int test_sequences = -1;         // -1: the preset's.
  std::string scene_file;          // YAML floor plan; empty: generated from the seed.
  std::string layout = "splits";   // splits | single.
  std::string image_format = "jpg";
  bool lidar = true;
  bool cameras = true;
  bool masks = true;
  bool depth = false;

  static void Declare(ParamSchema<SimulatorOptions>& s) {
    s.Add("preset", &SimulatorOptions::preset, "Recording size: tiny (tests), small (demo), large (benchmark)")
        .Choices({"tiny", "small", "large"});
    s.Add("seed", &SimulatorOptions::seed, "Random seed of the floor, routes, people and noise").Min(0);
    s.Add("crowdedness", &SimulatorOptions::crowdedness, "People per 100 m^2 of floor (-1: preset's)")
        .Range(-1, 50);
    s.Add("query_crowdedness", &SimulatorOptions::query_crowdedness,
          "People per 100 m^2 in the query sequences only, the mapping ones unchanged (-1: as crowdedness)")
        .Range(-1, 50);
    s.Add("scale", &SimulatorOptions::scale, "Image resolution factor of every camera (0: preset's)")
        .Range(0, 1);
    s.Add("duration_scale", &SimulatorOptions::duration_scale, "Multiplies every sequence's duration")
        .Range(0.05, 100);
    s.Add("mapping_sequences", &SimulatorOptions::mapping_sequences, "Mapping sequences (0: preset's)")
        .Range(0, 1000);
    s.Add("validation_sequences", &SimulatorOptions::validation_sequences,
          "Query sequences in the validation area (-1: preset's)").Range(-1, 1000);
    s.Add("test_sequences", &SimulatorOptions::test_sequences, "Query sequences in the test area (-1: preset's)")
        .Range(-1, 1000);
    s.Add("scene_file", &SimulatorOptions::scene_file, "YAML floor plan (README); empty: generated from the seed")
        .Path();
    s.Add("layout", &SimulatorOptions::layout,
          "splits: mapping kapture at the root, queries in validation/ and test/; single: one kapture")
        .Choices({"splits", "single"});
    s.Add("image_format", &SimulatorOptions::image_format, "Image files").Choices({"jpg", "png"});
    s.Add("lidar", &SimulatorOptions::lidar, "Write the two LiDARs' scans (PCD)");
    s.Add("cameras", &SimulatorOptions::cameras,
          "Render and write the camera images (false: LiDAR and wheel records only, e.g. for LiDAR sweeps)");
    s.Add("masks", &SimulatorOptions::masks, "Write the true per-pixel person masks");
    s.Add("depth", &SimulatorOptions::depth,
          "Write the true depth maps: truth/depth/<split>/<seq>/<camera>/<timestamp>.depth (float32 z in m, 0: none)");
  }

  SimOptions ToSimOptions() const {
    SimOptions o = PresetOptions(preset);
    o.seed = static_cast<uint64_t>(seed);
    if (crowdedness >= 0) o.crowdedness = crowdedness;
    o.query_crowdedness = query_crowdedness;
    if (scale > 0) o.rig.image_scale = scale;
    o.mapping_duration_s *= duration_scale;
    o.query_duration_s *= duration_scale;
    if (mapping_sequences > 0) o.mapping_sequences = mapping_sequences;
    if (validation_sequences >= 0) o.validation_sequences = validation_sequences;
    if (test_sequences >= 0) o.test_sequences = test_sequences;
    o.scene_file = scene_file;
    o.layout = layout;
    o.image_format = image_format;
    o.lidar = lidar;
    o.cameras = cameras;
    o.masks = masks;
    o.depth = depth;
    return o;
  }

  bool Check(std::string* why) const {
    try {
      return ToSimOptions().Check(why);
    } catch (const Error& e) {
      *why = e.what();
      return false;
    }
  }
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
    const DatasetSummary s = GenerateDataset(options().ToSimOptions(), ctx.output_dir(), ctx.threads(), hooks);
    ctx.Info("simulated " + std::to_string(s.sequences.size()) + " sequences: " + std::to_string(s.images) +
             " images, " + std::to_string(s.scans) + " LiDAR scans");
  }
};

LOCFORGE_REGISTER_STAGE(Simulator)

}  // namespace locforge::source

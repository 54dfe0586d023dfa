// A whole simulated recording: presets, the plan of sequences (mapping and
// query ones, days apart), and the writer of the kapture dataset with its
// ground truth. Deterministic for a seed, whatever the number of threads.
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_DATASET_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_DATASET_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "camera_rig.h"
#include "locforge/fs.h"
#include "platform.h"
#include "scene.h"

namespace locforge::sim {

struct SimOptions {
  uint64_t seed = 0;
  FloorOptions floor;               // used when scene_file is empty
  std::string scene_file;           // YAML floor plan (README.md), "" = generated from the seed
  RigOptions rig;
  WheelOptions wheels;
  MotionLimits limits;
  int mapping_sequences = 1;
  int validation_sequences = 1;
  int test_sequences = 1;
  double mapping_duration_s = 8;
  double query_duration_s = 4;
  double crowdedness = 2.0;         // people per 100 m^2 of floor
  double query_crowdedness = -1;    // validation and test sequences only; < 0: crowdedness
  bool lidar = true;                // write LiDAR scans
  bool cameras = true;              // render and write camera images (false: LiDAR + wheels only)
  bool masks = true;                // write person masks
  bool depth = false;               // write the exact depth maps (kapture .depth: float32 z, 0 = none)
  std::string image_format = "jpg"; // jpg | png
  std::string layout = "splits";    // splits: mapping kapture at the root, queries in validation/, test/; single: one kapture
  int texture_size = 512;           // texels per texture side
  bool Check(std::string* why) const;

  // The options a graph sets, declared once (source/simulator binds them in
  // place over a preset: Derived() ones keep the preset's value unless given).
  template <typename Schema>
  static void Declare(Schema& s) {
    s.Add("seed", &SimOptions::seed, "Random seed of the floor, routes, people and noise").Min(0);
    s.Add("crowdedness", &SimOptions::crowdedness, "People per 100 m^2 of floor (default: the preset's)")
        .Range(0, 50).Derived();
    s.Add("query_crowdedness", &SimOptions::query_crowdedness,
          "People per 100 m^2 in the query sequences only, the mapping ones unchanged (-1: as crowdedness)")
        .Range(-1, 50);
    s.Add("scale", &SimOptions::rig, &RigOptions::image_scale,
          "Image resolution factor of every camera, 1 = full sensor (default: the preset's)")
        .Range(1e-6, 1).Derived();
    s.Add("mapping_sequences", &SimOptions::mapping_sequences, "Mapping sequences (default: the preset's)")
        .Range(1, 1000).Derived();
    s.Add("validation_sequences", &SimOptions::validation_sequences,
          "Query sequences in the validation area (default: the preset's)").Range(0, 1000).Derived();
    s.Add("test_sequences", &SimOptions::test_sequences,
          "Query sequences in the test area (default: the preset's)").Range(0, 1000).Derived();
    s.Add("scene_file", &SimOptions::scene_file, "YAML floor plan (README); empty: generated from the seed")
        .Path();
    s.Add("layout", &SimOptions::layout,
          "splits: mapping kapture at the root, queries in validation/ and test/; single: one kapture")
        .Choices({"splits", "single"});
    s.Add("image_format", &SimOptions::image_format, "Image files").Choices({"jpg", "png"});
    s.Add("lidar", &SimOptions::lidar, "Write the two LiDARs' scans (PCD)");
    s.Add("cameras", &SimOptions::cameras,
          "Render and write the camera images (false: LiDAR and wheel records only, e.g. for LiDAR sweeps)");
    s.Add("masks", &SimOptions::masks, "Write the true per-pixel person masks");
    s.Add("depth", &SimOptions::depth,
          "Write the true depth maps: truth/depth/<split>/<seq>/<camera>/<timestamp>.depth (float32 z in m, 0: none)");
  }
};

// "tiny" (unit tests, seconds), "small" (the demo), "large" (thousands of images).
SimOptions PresetOptions(const std::string& preset);

struct SequencePlan {
  std::string name;   // e.g. "map_00", "val_00", "test_00"
  std::string split;  // mapping | validation | test
  int day = 0;        // appearance session (signage, exposure, crowd)
  double duration_s = 0;
  Timestamp t0_us = 0;  // timestamp of trajectory time 0 (microseconds)
  uint64_t seed = 0;
};

std::vector<SequencePlan> PlanSequences(const SimOptions& options);

struct SequenceSummary {
  SequencePlan plan;
  double distance_m = 0;
  double odometry_drift = 0;     // dead-reckoning end error / distance
  int images = 0, scans = 0, people = 0;
  double person_fraction = 0;    // mean fraction of image pixels showing people
};

struct DatasetSummary {
  std::vector<SequenceSummary> sequences;
  int images = 0, scans = 0;
  double render_seconds = 0;     // wall time spent rendering + encoding images
};

struct Hooks {
  std::function<void(const std::string&)> log;
  std::function<void(uint64_t done, uint64_t total)> progress;
  std::function<bool()> cancelled;  // true -> stop (throws Cancelled)
};

// Writes the dataset under `out` (layout in README.md). `threads` >= 1.
DatasetSummary GenerateDataset(const SimOptions& options, const fs::path& out, int threads,
                               const Hooks& hooks = {});

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_DATASET_H_

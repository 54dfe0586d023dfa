// The example stages (source/synthetic_images, source/image_list,
// example/image_stats): declared here, defined one per file in their kind's
// folder, listed by that kind's plugin.cc.
#ifndef LOCFORGE_PLUGINS_COMMON_EXAMPLES_EXAMPLE_STAGES_H_
#define LOCFORGE_PLUGINS_COMMON_EXAMPLES_EXAMPLE_STAGES_H_

#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "kapture_text.h"
#include "locforge/plugin.h"

namespace locforge::examples {

// ---- source/synthetic_images ------------------------------------------------

struct SyntheticImagesOptions {
  int count = 8;        // Images generated.
  int width = 64;       // Image width in pixels.
  int height = 48;      // Image height in pixels.
  int64_t seed = 0;     // Same seed, same images (bit for bit).
  bool color = false;   // Three channels instead of one.
  static void Declare(ParamSchema<SyntheticImagesOptions>& s) {
    s.Add("count", &SyntheticImagesOptions::count, "Number of images generated").Range(1, 1000000);
    s.Add("width", &SyntheticImagesOptions::width, "Image width in pixels").Range(8, 16384);
    s.Add("height", &SyntheticImagesOptions::height, "Image height in pixels").Range(8, 16384);
    s.Add("seed", &SyntheticImagesOptions::seed, "Random seed; the same seed gives the same images");
    s.Add("color", &SyntheticImagesOptions::color, "Three-channel colour images instead of grayscale");
  }
};

class SyntheticImages : public Stage<SyntheticImagesOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"source", "synthetic_images",
            "Generates deterministic procedural textured images as a kapture dataset",
            {},
            {{"images", "kapture.dataset", "One PINHOLE camera and its image records"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

// ---- source/image_list ------------------------------------------------------

struct ImageListOptions {
  std::string root;                                          // Folder imported.
  std::vector<std::string> extensions = {"png", "jpg", "jpeg"};  // Case-insensitive.
  double focal_px = 0;  // Placeholder focal length; 0: 1.2 * max(width, height).
  static void Declare(ParamSchema<ImageListOptions>& s) {
    s.Add("root", &ImageListOptions::root, "Folder of images imported (searched recursively)")
        .Path()
        .Required();
    s.Add("extensions", &ImageListOptions::extensions,
          "File extensions imported, case-insensitive");
    s.Add("focal_px", &ImageListOptions::focal_px,
          "Placeholder focal length in pixels; 0 uses 1.2 * max(width, height)")
        .Min(0);
  }
};

class ImageList : public Stage<ImageListOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"source", "image_list",
            "Imports a folder of images as a kapture dataset (one camera per image size)",
            {},
            {{"images", "kapture.dataset", "Cameras and image records of the folder"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

// ---- example/image_stats ----------------------------------------------------

struct ImageStatsOptions {
  int bins = 16;  // Histogram bins over the full intensity range.
  static void Declare(ParamSchema<ImageStatsOptions>& s) {
    s.Add("bins", &ImageStatsOptions::bins, "Histogram bins over the intensity range")
        .Range(1, 256);
  }
};

class ImageStats : public PerItemStage<ImageStatsOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"example", "image_stats",
            "Per-image intensity mean, std, min, max and histogram, plus a CSV summary",
            {{"images", "kapture.dataset", "Dataset whose camera images are measured"}},
            {{"stats", "report", "stats/<image>.json per image and stats.csv"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using PerItemStage::PerItemStage;
  std::vector<std::string> ListItems(RunContext& ctx) override;
  void ProcessItem(RunContext& ctx, const std::string& item) override;
  void Finalize(RunContext& ctx) override;

 private:
  // Records of the input dataset by image path, read once per instance.
  const ImageRecord& Record(RunContext& ctx, const std::string& image);
  void LoadRecords(RunContext& ctx);

  std::mutex mutex_;
  bool loaded_ = false;
  std::map<std::string, ImageRecord> records_;
};

}  // namespace locforge::examples

#endif  // LOCFORGE_PLUGINS_COMMON_EXAMPLES_EXAMPLE_STAGES_H_

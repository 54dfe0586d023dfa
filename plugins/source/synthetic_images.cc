// Procedural textures: a few random plane waves, blocky value noise and
// rectangles, so images have gradients and corners (useful to feature stages)
// and depend only on (seed, index, size).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "locforge/fs.h"
#include "kapture_text.h"
#include "locforge/plugin.h"

namespace locforge::source {

using namespace ::locforge::examples;  // the library this stage wires

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

namespace {

// splitmix64: tiny, and unlike <random> distributions identical everywhere.
struct Rng {
  uint64_t state;
  uint64_t Next() {
    uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * (Next() >> 11) * 0x1.0p-53; }
};

uint64_t Hash(uint64_t a, uint64_t b) {
  Rng r{a * 0x100000001B3ull ^ b};
  return r.Next();
}

cv::Mat MakeImage(const SyntheticImagesOptions& o, int index) {
  const int channels = o.color ? 3 : 1;
  cv::Mat image(o.height, o.width, channels == 3 ? CV_8UC3 : CV_8UC1);
  Rng rng{static_cast<uint64_t>(o.seed) * 0x9E3779B97F4A7C15ull + static_cast<uint64_t>(index)};
  struct Wave { double fx, fy, phase, amp; };
  struct Rect { int x0, y0, x1, y1; double delta; };
  std::vector<Wave> waves[3];
  for (int c = 0; c < channels; ++c)
    for (int k = 0; k < 3; ++k)
      waves[c].push_back({rng.Uniform(-6, 6), rng.Uniform(-6, 6), rng.Uniform(0, 6.283185307179586),
                          rng.Uniform(10, 40)});
  std::vector<Rect> rects;
  for (int k = 0; k < 6; ++k) {
    const int x0 = static_cast<int>(rng.Uniform(0, o.width)), y0 = static_cast<int>(rng.Uniform(0, o.height));
    rects.push_back({x0, y0, x0 + 1 + static_cast<int>(rng.Uniform(0, o.width / 3.0)),
                     y0 + 1 + static_cast<int>(rng.Uniform(0, o.height / 3.0)), rng.Uniform(-60, 60)});
  }
  const uint64_t noise_seed = rng.Next();
  const int cell = 4;  // value-noise block size in pixels
  for (int y = 0; y < o.height; ++y) {
    uint8_t* row = image.ptr<uint8_t>(y);
    for (int x = 0; x < o.width; ++x) {
      double rect = 0;
      for (const auto& r : rects)
        if (x >= r.x0 && x < r.x1 && y >= r.y0 && y < r.y1) rect += r.delta;
      const uint64_t block = (static_cast<uint64_t>(y / cell) << 32) | static_cast<uint64_t>(x / cell);
      for (int c = 0; c < channels; ++c) {
        double v = 128 + rect;
        for (const auto& w : waves[c])
          v += w.amp * std::sin(6.283185307179586 * (w.fx * x / o.width + w.fy * y / o.height) + w.phase);
        v += static_cast<double>(Hash(noise_seed + c, block) % 33) - 16;
        row[x * channels + c] = cv::saturate_cast<uint8_t>(std::lround(v));
      }
    }
  }
  return image;
}

}  // namespace

void SyntheticImages::Run(RunContext& ctx) {
  const auto& o = options();
  const fs::path dataset = ctx.output_dir();
  std::vector<ImageRecord> records;
  for (int i = 0; i < o.count; ++i) {
    ctx.ThrowIfCancelled();
    char name[32];
    std::snprintf(name, sizeof(name), "cam0/%05d.png", i);
    std::vector<uchar> png;
    if (!cv::imencode(".png", MakeImage(o, i), png)) throw Error("cannot encode PNG " + std::string(name));
    WriteFileAtomic(RecordsDataDir(dataset) / name,
                    std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
    records.push_back({i, "cam0", name, 0});
    ctx.Progress(i + 1, o.count, name);
  }
  PinholeCamera camera{"cam0", "synthetic", o.width, o.height,
                       1.2 * std::max(o.width, o.height), 1.2 * std::max(o.width, o.height),
                       o.width / 2.0, o.height / 2.0};
  WriteCameraDataset(dataset, {camera}, records);
  ctx.Info("generated " + std::to_string(o.count) + " images");
}

LOCFORGE_REGISTER_STAGE(SyntheticImages)

}  // namespace locforge::source

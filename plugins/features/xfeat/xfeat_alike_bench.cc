// Seconds per image of features/xfeat and features/alike (and features/sift
// for scale) on a real photograph at 1 and 2 OpenCV threads, wall clock and
// process CPU time (the latter is less sensitive to other load on the machine).
//   locforge_xfeat_alike_bench [--image JPG] [--models DIR] [--repeat N] [--only NAME]  (--help)
// Default image: ../shared/data/localization/strecha_fountain-P11/mapping/
// sensors/records_data/0000.jpg (1536x1024); models: build/models.
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <functional>
#include <iostream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "alike.h"
#include "locforge/param_cli.h"
#include "sift.h"
#include "xfeat.h"

namespace fs = std::filesystem;
using namespace locforge::learned;

namespace {

double CpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

struct BenchOptions {
  std::string image = std::string(LOCFORGE_SHARED_DIR_FOR_BENCH) +
                      "/data/localization/strecha_fountain-P11/mapping/sensors/records_data/0000.jpg";
  std::string models = LOCFORGE_LEARNED_MODEL_DIR_FOR_BENCH;
  int repeat = 3;
  std::string only;
  static void Declare(locforge::ParamSchema<BenchOptions>& s) {
    s.Add("image", &BenchOptions::image, "Photograph to time (default: fountain-P11 0000.jpg, 1536x1024)");
    s.Add("models", &BenchOptions::models, "Folder of xfeat.onnx and alike-{t,s,n,l}.onnx (build/models)");
    s.Add("repeat", &BenchOptions::repeat, "Runs per thread count, after one warm-up").Min(1);
    s.Add("only", &BenchOptions::only, "Only the extractors whose name contains this (xfeat, alike-n, sift)");
  }
};

}  // namespace

int main(int argc, char** argv) {
  BenchOptions b;
  if (const int code = locforge::ParseToolOptions(
          argc, argv, "locforge_xfeat_alike_bench: seconds per image of XFeat, ALIKE and SIFT at 1 and 2 threads\n", &b);
      code >= 0)
    return code;
  const std::string image = b.image, models = b.models, only = b.only;
  const int repeat = b.repeat;
  const cv::Mat bgr = cv::imread(image, cv::IMREAD_COLOR);
  if (bgr.empty()) {
    std::cerr << image << ": cannot read\n";
    return 1;
  }
  cv::Mat rgb, grey;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);

  struct Extractor {
    std::string name;
    std::function<int()> run;  // returns the keypoint count
  };
  std::vector<Extractor> extractors;
  XfeatOptions xo;
  xo.model = models + "/xfeat.onnx";
  if (fs::exists(xo.model)) extractors.push_back({"xfeat", [&] { return ExtractXfeat(rgb, xo).count(); }});
  for (const char* size : {"t", "s", "n", "l"}) {
    AlikeOptions ao;
    ao.model = models + "/alike-" + size + ".onnx";
    if (fs::exists(ao.model))
      extractors.push_back({std::string("alike-") + size, [&rgb, ao] { return ExtractAlike(rgb, ao).count(); }});
  }
  extractors.push_back({"sift", [&] {
                          locforge::sift::SiftOptions so;
                          so.contrast_threshold = 0.01;  // the default recipe's
                          return locforge::sift::ExtractSift(grey, so).count();
                        }});

  std::printf("%s (%dx%d), mean of %d runs after one warm-up\n\n", image.c_str(), rgb.cols, rgb.rows, repeat);
  std::printf("| extractor | keypoints | 1 thread: wall s/image | CPU s/image | 2 threads: wall s/image | CPU s/image |\n");
  std::printf("|---|---|---|---|---|---|\n");
  for (const auto& e : extractors) {
    if (!only.empty() && e.name.find(only) == std::string::npos) continue;
    int count = e.run();  // warm-up: model load
    double wall[2], cpu[2];
    for (int threads : {1, 2}) {
      cv::setNumThreads(threads);
      const auto start = std::chrono::steady_clock::now();
      const double cpu_start = CpuSeconds();
      for (int i = 0; i < repeat; ++i) count = e.run();
      wall[threads - 1] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / repeat;
      cpu[threads - 1] = (CpuSeconds() - cpu_start) / repeat;
    }
    std::printf("| %s | %d | %.3f | %.3f | %.3f | %.3f |\n", e.name.c_str(), count, wall[0], cpu[0], wall[1], cpu[1]);
    std::fflush(stdout);
  }
  return 0;
}

// Time per image of each learned extractor at 1 and 2 OpenCV threads, at the
// simulator's `small` image size (648 x 512) and at full 2592 x 2048, with the
// plugin's own resizing (R2D2: network at longer side <= max_size, 1024;
// D2-Net: max_edge 1600 / max_sum_edges 2800; global: each model's policy).
//
//   locforge_learned_bench [--r2d2 MODEL.onnx] [--repeat N] [--sizes small,full] [--only NAME]
//
// Each extractor first runs once on a 96x96 image (model load, allocations),
// then `repeat` timed runs per size and thread count.
//
// SIFT (plugins/features/sift, OpenCV, on the grey image, default options)
// is the reference. R2D2 runs the real shipped models (r2d2_WASF_N16 and,
// when beside it, faster2d2_WASF_N16). D2-Net, NetVLAD, AP-GeM and DELG run the
// small architecture-faithful models of testdata/onnx_models.py (generated
// here with python3-onnx): their times measure our pre/post-processing and a
// tiny network, NOT the cost of the authors' VGG16/ResNet101 weights.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <iostream>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <unistd.h>
#include <string>
#include <vector>

#include "d2net.h"
#include "global_descriptor.h"
#include "locforge/fs.h"
#include "r2d2.h"
#include "sift.h"

namespace {

using namespace locforge::learned;
namespace fs = std::filesystem;

cv::Mat Image(int w, int h) {
  cv::Mat rgb(h, w, CV_8UC3);
  cv::randu(rgb, cv::Scalar::all(0), cv::Scalar::all(255));
  cv::Mat smooth;
  cv::GaussianBlur(rgb, smooth, cv::Size(0, 0), 2.0);
  return smooth;
}

double TimeIt(const std::function<void()>& f, int repeat) {
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < repeat; ++i) f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / repeat;
}

}  // namespace

int main(int argc, char** argv) {
  std::string r2d2 = std::string(LOCFORGE_SHARED_DIR_FOR_BENCH) + "/models/r2d2/r2d2_WASF_N16.onnx";
  int repeat = 2;
  std::string sizes = "small,full";
  std::string only;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--r2d2") r2d2 = argv[i + 1];
    else if (a == "--repeat") repeat = std::atoi(argv[i + 1]);
    else if (a == "--sizes") sizes = argv[i + 1];
    else if (a == "--only") only = argv[i + 1];
    else {
      std::cerr << "usage: locforge_learned_bench [--r2d2 MODEL] [--repeat N] [--sizes small,full] [--only NAME]\n";
      return 2;
    }
  }
  const std::string python = LOCFORGE_ONNX_PYTHON;
  const fs::path dir = fs::temp_directory_path() / ("learned_bench_" + std::to_string(getpid()));
  fs::create_directories(dir);
  bool generated = false;
  if (!python.empty()) {
    const std::string cmd = python + " " + LOCFORGE_LEARNED_MODELS_SCRIPT + " make " + dir.string() +
                            " 480 640";
    generated = std::system(cmd.c_str()) == 0;
  }
  if (!generated) std::cerr << "no python3 with onnx + numpy: only R2D2 is timed\n";

  struct Extractor {
    std::string name;
    std::function<void(const cv::Mat&)> run;
  };
  std::vector<Extractor> extractors;
  // R2D2 with one model: the authors' multi-scale extraction, or a single
  // scale at longer side 648 (the network at 648x512 for both image sizes).
  auto add_r2d2 = [&](const std::string& model) {
    const std::string stem = fs::path(model).stem().string();
    for (const bool single : {false, true})
      extractors.push_back(
          {"r2d2 (" + stem + ", real weights, " +
               (single ? "single scale, longer side 648)" : "multi-scale)"),
           [=](const cv::Mat& im) {
             R2d2Options o;
             o.model = model;
             if (single) o.min_size = o.max_size = 648;
             ExtractR2d2(im, o);
           }});
  };
  if (fs::exists(r2d2)) {
    add_r2d2(r2d2);
    const std::string fast = (fs::path(r2d2).parent_path() / "faster2d2_WASF_N16.onnx").string();
    if (fs::exists(fast)) add_r2d2(fast);
  } else {
    std::cerr << r2d2 << " not found: R2D2 not timed\n";
  }
  extractors.push_back({"sift (OpenCV, features/sift defaults, grey image)", [](const cv::Mat& im) {
                          cv::Mat gray;
                          cv::cvtColor(im, gray, cv::COLOR_RGB2GRAY);
                          locforge::sift::ExtractSift(gray, locforge::sift::SiftOptions());
                        }});
  if (generated) {
    const std::string d = dir.string();
    extractors.push_back({"d2net (generated tiny model, single scale)", [=](const cv::Mat& im) {
                            D2netOptions o;
                            o.model = d + "/d2net.onnx";
                            ExtractD2net(im, o);
                          }});
    extractors.push_back({"d2net (generated tiny model, scales 0.5,1,2)", [=](const cv::Mat& im) {
                            D2netOptions o;
                            o.model = d + "/d2net.onnx";
                            o.scales = {0.5, 1, 2};
                            ExtractD2net(im, o);
                          }});
    extractors.push_back({"netvlad (generated tiny model, fixed 640x480)", [=](const cv::Mat& im) {
                            GlobalOptions o = GlobalOptions::Defaults(GlobalModel::kNetVlad);
                            o.model = d + "/netvlad.onnx";
                            ExtractGlobal(im, o);
                          }});
    extractors.push_back({"apgem (generated tiny GeM model, max side 1024)", [=](const cv::Mat& im) {
                            GlobalOptions o = GlobalOptions::Defaults(GlobalModel::kApGem);
                            o.model = d + "/gem.onnx";
                            ExtractGlobal(im, o);
                          }});
    extractors.push_back({"delg (generated tiny GeM model, 3 scales, max side 1024)", [=](const cv::Mat& im) {
                            GlobalOptions o = GlobalOptions::Defaults(GlobalModel::kDelg);
                            o.model = d + "/gem.onnx";
                            ExtractGlobal(im, o);
                          }});
  }

  std::vector<std::pair<std::string, cv::Mat>> images;
  if (sizes.find("small") != std::string::npos) images.emplace_back("648x512", Image(648, 512));
  if (sizes.find("full") != std::string::npos) images.emplace_back("2592x2048", Image(2592, 2048));

  std::printf("| extractor | image | 1 thread (s/image) | 2 threads (s/image) | speed-up |\n");
  std::printf("|---|---|---|---|---|\n");
  const cv::Mat warm_up = Image(96, 96);
  for (const auto& e : extractors) {
    if (!only.empty() && e.name.find(only) == std::string::npos) continue;
    try {
      e.run(warm_up);
    } catch (const std::exception&) {
      // too small for some settings (e.g. a single R2D2 scale); the model is loaded anyway
    }
    for (const auto& [label, image] : images) {
      double t[2];
      for (int threads : {1, 2}) {
        cv::setNumThreads(threads);
        t[threads - 1] = TimeIt([&] { e.run(image); }, repeat);
      }
      std::printf("| %s | %s | %.3f | %.3f | %.2f |\n", e.name.c_str(), label.c_str(), t[0], t[1],
                  t[0] / t[1]);
      std::fflush(stdout);
    }
  }
  fs::remove_all(dir);
  return 0;
}

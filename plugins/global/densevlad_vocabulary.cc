// global/densevlad_vocabulary: the DenseVLAD visual words, learnt on the map
// images (library: densevlad/).
#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <opencv2/core.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "densevlad.h"
#include "densevlad_io.h"
#include "global_features.h"
#include "locforge/kapture/csv.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::global {

using namespace ::locforge::retrieval;  // the library this stage wires

namespace {

namespace k = locforge::kapture;

struct VocabularyOptions {
  int clusters = 64;
  int sample_size = 100000;
  int iterations = 20;
  int seed = 0;
  int pca_dims = 0;
  int pca_max_images = 2000;
  int max_image_size = 480;
  int grid_step = 4;
  std::vector<double> bin_sizes = {4, 6, 8, 10};
  std::string file;
  static void Declare(ParamSchema<VocabularyOptions>& s) {
    s.Add("clusters", &VocabularyOptions::clusters, "visual words (VLAD has clusters x 128 dims)")
        .Range(2, 4096);
    s.Add("sample_size", &VocabularyOptions::sample_size,
          "dense descriptors sampled over the map images for k-means").Min(100);
    s.Add("iterations", &VocabularyOptions::iterations, "k-means iterations").Range(1, 1000);
    s.Add("seed", &VocabularyOptions::seed, "k-means++ seed").Min(0);
    s.Add("pca_dims", &VocabularyOptions::pca_dims,
          "PCA-whitening dimensions learnt on the map (0: no PCA; at most images - 1)").Min(0);
    s.Add("pca_max_images", &VocabularyOptions::pca_max_images,
          "map images (evenly spaced) used to learn the PCA").Min(2);
    s.Add("max_image_size", &VocabularyOptions::max_image_size,
          "images downscaled so the longer side is at most this (0: never)").Min(0);
    s.Add("grid_step", &VocabularyOptions::grid_step, "pixels between dense SIFT grid points")
        .Range(1, 64);
    s.Add("bin_sizes", &VocabularyOptions::bin_sizes, "SIFT bin widths of the scales (pixels)")
        .Range(1, 64);
    s.Add("file", &VocabularyOptions::file,
          "load this vocabulary file (a densevlad_vocabulary.bin) instead of training; "
          "empty: train (a plain string: its content does not enter the cache key)");
  }
  bool Check(std::string* why) const {
    if (bin_sizes.empty() || bin_sizes.size() >= 16) {
      *why = "parameter 'bin_sizes': give 1 to 15 scales";
      return false;
    }
    if (sample_size < clusters) {
      *why = "parameter 'sample_size': below 'clusters'";
      return false;
    }
    return true;
  }
};

class VocabularyStage : public Stage<VocabularyOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"global", "densevlad_vocabulary",
            "DenseVLAD visual vocabulary (k-means on dense RootSIFT) and PCA-whitening, learnt on the map",
            {{"images", "kapture.dataset", "map images to learn from (unused with 'file')", LF_PORT_OPTIONAL}},
            {{"vocabulary", "densevlad.vocabulary", "densevlad_vocabulary.bin"}}};
    meta.version = "2.1.0";  // 2.0.0: vl_dsift-style dense SIFT (descriptors differ from 1.0.0); 2.1.0: a damaged image fails
    return meta;
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const auto& o = options();
    if (!o.file.empty()) {
      const std::string bytes = ReadFile(o.file);
      (void)Vocabulary::Parse(bytes, o.file);
      WriteFileAtomic(ctx.output_dir() / kVocabularyFile, bytes);
      return;
    }
    if (!ctx.HasInput("images"))
      throw InputError("images", 0, "", "wire map images or give 'file'");
    const fs::path dataset = ctx.Input("images");
    const auto images = CameraImages(dataset);
    if (images.empty()) throw InputError(dataset.string(), 0, "records_camera.txt", "no images");
    Vocabulary v;
    v.dense = {o.max_image_size, o.grid_step, o.bin_sizes};
    // Evenly strided descriptors of every image.
    const int64_t per_image = (o.sample_size + images.size() - 1) / images.size();
    std::vector<RowMatrix> samples(images.size());
    ParallelFor(images.size(), ctx.threads(), [&](int64_t i) {
      ctx.ThrowIfCancelled();
      const RowMatrix d = DenseRootSift(ReadGray(dataset, images[i]), v.dense);
      const int64_t take = std::min<int64_t>(per_image, d.rows());
      samples[i].resize(take, 128);
      for (int64_t j = 0; j < take; ++j) samples[i].row(j) = d.row(j * d.rows() / take);
    });
    int64_t total = 0;
    for (const auto& s : samples) total += s.rows();
    RowMatrix all(total, 128);
    int64_t at = 0;
    for (const auto& s : samples) all.middleRows(at, s.rows()) = s, at += s.rows();
    ctx.Info("k-means: " + std::to_string(total) + " descriptors of " + std::to_string(images.size()) +
             " images into " + std::to_string(o.clusters) + " words");
    v.centres = KMeans(all, o.clusters, o.iterations, static_cast<uint64_t>(o.seed));
    if (o.pca_dims > 0) {
      const int64_t n = std::min<int64_t>(o.pca_max_images, images.size());
      RowMatrix vlads(n, v.centres.size());
      ParallelFor(n, ctx.threads(), [&](int64_t i) {
        ctx.ThrowIfCancelled();
        const auto& image = images[i * images.size() / n];
        vlads.row(i) = Vlad(DenseRootSift(ReadGray(dataset, image), v.dense), v.centres).transpose();
      });
      LearnPcaWhitening(vlads, o.pca_dims, &v);
      ctx.Info("PCA-whitening: " + std::to_string(v.pca_projection.rows()) + " dims from " +
               std::to_string(n) + " images");
    }
    WriteFileAtomic(ctx.output_dir() / kVocabularyFile, v.Serialize());
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(VocabularyStage)

}  // namespace locforge::global

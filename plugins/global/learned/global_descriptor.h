// ONNX global image descriptors (global/netvlad, global/apgem, global/delg):
// one implementation, per-model defaults for preprocessing and
// post-processing. Contracts: README.md "Global descriptors".
//
// Pipeline per image (8-bit RGB):
//   1. resize policy: "none"; "max_side" (downscale so the longer side is at
//      most max_side; never upscale); "fixed" (width x height, aspect not kept);
//   2. for each factor of `scales` (relative to the resized image; DELG's
//      multi-scale), channels in `channel_order`, value = (pixel - mean) / std
//      with pixel in [0, 255], as a 1x3xHxW float blob into input `input`;
//   3. the `output` of the network (any shape of N values: 1xD, 1xDx1x1) is the
//      descriptor at that scale, L2-normalised; the scales are summed and the
//      sum L2-normalised (one scale: just the L2 normalisation);
//   4. optional PCA-whitening from a file: y = P (x - m), first pca_dims rows,
//      then L2 again.
#ifndef LOCFORGE_PLUGINS_GLOBAL_LEARNED_GLOBAL_DESCRIPTOR_H_
#define LOCFORGE_PLUGINS_GLOBAL_LEARNED_GLOBAL_DESCRIPTOR_H_

#include <string>
#include <vector>

#include "locforge/params.h"

namespace cv {
class Mat;
}

namespace locforge::learned {

enum class GlobalModel { kNetVlad, kApGem, kDelg };

struct GlobalOptions {
  std::string model;                  // .onnx file (required).
  std::string input = "image";        // Input tensor name (1x3xHxW float32).
  std::string output = "descriptor";  // Output tensor name ("": the net's last output).
  std::string resize = "max_side";    // "none", "max_side" or "fixed".
  int max_side = 1024;                // Longer side limit of "max_side" (downscale only).
  int width = 640, height = 480;      // Size of "fixed".
  std::vector<double> scales = {1.0};  // Factors of the resized image; descriptors summed.
  std::string channel_order = "RGB";  // "RGB" or "BGR": channel order of the blob.
  std::vector<double> mean = {123.675, 116.28, 103.53};  // Per blob channel, pixel units.
  std::vector<double> std = {58.395, 57.12, 57.375};     // Per blob channel, pixel units.
  std::string pca_file;               // PCA-whitening file (README format); "": none.
  int pca_dims = 0;                   // Rows of the PCA kept (0: all of the file).
  std::string type;                   // kapture global features type (folder name).

  // The defaults of each model's contract (README.md).
  static GlobalOptions Defaults(GlobalModel model);
  bool Check(std::string* why) const;
};

// Declares the parameters of GlobalOptions on a schema of a type deriving
// from it (each stage's options type carries its model's defaults).
template <typename O>
void DeclareGlobalOptions(ParamSchema<O>& s) {
  s.template Add<std::string>("model", &GlobalOptions::model, "ONNX model file (README contract)")
      .Path()
      .Required();
  s.template Add<std::string>("input", &GlobalOptions::input, "input tensor name (1x3xHxW float32)");
  s.template Add<std::string>("output", &GlobalOptions::output,
                              "output tensor name (empty: the network's last output)");
  s.template Add<std::string>("resize", &GlobalOptions::resize,
                              "resize policy: none, max_side (downscale only) or fixed")
      .Choices({"none", "max_side", "fixed"});
  s.template Add<int>("max_side", &GlobalOptions::max_side, "longer side limit of resize: max_side")
      .Range(16, 16384);
  s.template Add<int>("width", &GlobalOptions::width, "width of resize: fixed").Range(8, 16384);
  s.template Add<int>("height", &GlobalOptions::height, "height of resize: fixed").Range(8, 16384);
  s.template Add<std::vector<double>>("scales", &GlobalOptions::scales,
                                      "scale factors of the resized image; per-scale L2 "
                                      "descriptors are summed, then L2-normalised")
      .Range(0.05, 4);
  s.template Add<std::string>("channel_order", &GlobalOptions::channel_order,
                              "channel order of the input blob")
      .Choices({"RGB", "BGR"});
  s.template Add<std::vector<double>>("mean", &GlobalOptions::mean,
                                      "per blob channel, subtracted from pixels in [0, 255]");
  s.template Add<std::vector<double>>("std", &GlobalOptions::std,
                                      "per blob channel, divides (pixel - mean)");
  s.template Add<std::string>("pca_file", &GlobalOptions::pca_file,
                              "PCA-whitening file (README format; empty: none)")
      .Path();
  s.template Add<int>("pca_dims", &GlobalOptions::pca_dims,
                      "PCA rows kept (0: all rows of the file)")
      .Min(0);
  s.template Add<std::string>("type", &GlobalOptions::type, "kapture global features type (folder name)");
}

// PCA-whitening read from a file: "LFPCA1\0\0", int32 d_in, int32 d_out,
// float32 mean[d_in], float32 projection[d_out][d_in] (row-major), little-endian.
struct PcaWhitening {
  int d_in = 0, d_out = 0;
  std::vector<float> mean, projection;
  // Throws InputError naming the file (bad magic, sizes, truncated).
  static PcaWhitening Read(const std::string& file, int keep_dims = 0);
  // y = P (x - m), L2-normalised.
  std::vector<float> Apply(const std::vector<float>& x) const;
};

// The blob the network gets at one scale: resize policy, then `scale`, then
// channel order and normalisation. 1x3xHxW CV_32F.
cv::Mat GlobalInputBlob(const cv::Mat& rgb, const GlobalOptions& options, double scale);

struct GlobalDescriptor {
  std::vector<float> values;       // L2-normalised (after PCA when given)
  std::vector<float> raw;          // the network's output at the first scale, as is
  std::vector<int> input_sizes;    // width, height of the blob at each scale
  double network_seconds = 0;
};

// Runs the whole pipeline on an 8-bit RGB image. `pca` may be null.
GlobalDescriptor ExtractGlobal(const cv::Mat& rgb, const GlobalOptions& options,
                               const PcaWhitening* pca = nullptr);

void L2Normalise(std::vector<float>* v);

}  // namespace locforge::learned

#endif  // LOCFORGE_PLUGINS_GLOBAL_LEARNED_GLOBAL_DESCRIPTOR_H_

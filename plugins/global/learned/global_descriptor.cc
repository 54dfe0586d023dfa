#include "global_descriptor.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>

#include "locforge/error.h"
#include "locforge/fs.h"
#include "onnx_net.h"
#include "locforge/kapture/features.h"

namespace locforge::learned {

GlobalOptions GlobalOptions::Defaults(GlobalModel model) {
  GlobalOptions o;
  switch (model) {
    case GlobalModel::kNetVlad:
      // Pitts30k VGG16 + NetVLAD (Nanne's pytorch-NetVLAD): RGB, ImageNet
      // mean/std; exported at a fixed input size (OpenCV 4.6 needs static
      // shapes for the channel-wise descriptor normalisation).
      o.resize = "fixed";
      o.width = 640;
      o.height = 480;
      o.type = "netvlad";
      break;
    case GlobalModel::kApGem:
      // deep-image-retrieval Resnet101-AP-GeM-LM18: RGB, ImageNet mean/std,
      // longer side <= 1024, one scale; GeM + FC whitening inside the model.
      o.resize = "max_side";
      o.max_side = 1024;
      o.type = "apgem";
      break;
    case GlobalModel::kDelg:
      // DELG global head (TF): (pixel - 128) / 128 on RGB, scales
      // 1/sqrt(2), 1, sqrt(2) of the image with longer side <= 1024, per-scale
      // descriptors L2-normalised, summed, L2-normalised.
      o.resize = "max_side";
      o.max_side = 1024;
      o.scales = {0.7071067811865476, 1.0, 1.4142135623730951};
      o.mean = {128, 128, 128};
      o.std = {128, 128, 128};
      o.type = "delg";
      break;
  }
  return o;
}

bool GlobalOptions::Check(std::string* why) const {
  if (model.empty()) {
    *why = "parameter 'model': the .onnx file is required";
    return false;
  }
  if (!kapture::IsFeatureTypeName(type)) {
    *why = "parameter 'type': '" + type + "' is not a folder name";
    return false;
  }
  if (mean.size() != 3 || std.size() != 3) {
    *why = "parameters 'mean' and 'std': give 3 values each (one per blob channel)";
    return false;
  }
  for (double s : std)
    if (!(s > 0)) {
      *why = "parameter 'std': values must be > 0";
      return false;
    }
  if (scales.empty()) {
    *why = "parameter 'scales': give at least one scale";
    return false;
  }
  if (input.empty()) {
    *why = "parameter 'input': the input tensor name is required";
    return false;
  }
  return true;
}

// ------------------------------------------------------------------ PCA file

PcaWhitening PcaWhitening::Read(const std::string& file, int keep_dims) {
  const std::string bytes = ReadFile(file);
  constexpr size_t kHeader = 8 + 2 * sizeof(int32_t);
  if (bytes.size() < kHeader || std::memcmp(bytes.data(), "LFPCA1\0\0", 8) != 0)
    throw InputError(file, 0, "pca_file", "not a PCA-whitening file (magic 'LFPCA1\\0\\0' expected)");
  int32_t dims[2];
  std::memcpy(dims, bytes.data() + 8, sizeof dims);
  if (dims[0] <= 0 || dims[1] <= 0)
    throw InputError(file, 0, "pca_file", "bad dimensions " + std::to_string(dims[0]) + " x " +
                                              std::to_string(dims[1]));
  const size_t expected = kHeader + sizeof(float) * (static_cast<size_t>(dims[0]) +
                                                     static_cast<size_t>(dims[0]) * dims[1]);
  if (bytes.size() != expected)
    throw InputError(file, 0, "pca_file", std::to_string(bytes.size()) + " bytes, expected " +
                                              std::to_string(expected) + " for " +
                                              std::to_string(dims[1]) + " x " +
                                              std::to_string(dims[0]));
  if (keep_dims > dims[1])
    throw InputError(file, 0, "pca_dims", "the file has " + std::to_string(dims[1]) +
                                              " rows, " + std::to_string(keep_dims) + " asked");
  PcaWhitening p;
  p.d_in = dims[0];
  p.d_out = keep_dims > 0 ? keep_dims : dims[1];
  p.mean.resize(p.d_in);
  p.projection.resize(static_cast<size_t>(p.d_out) * p.d_in);
  std::memcpy(p.mean.data(), bytes.data() + kHeader, sizeof(float) * p.d_in);
  std::memcpy(p.projection.data(), bytes.data() + kHeader + sizeof(float) * p.d_in,
              sizeof(float) * p.projection.size());
  return p;
}

std::vector<float> PcaWhitening::Apply(const std::vector<float>& x) const {
  if (static_cast<int>(x.size()) != d_in)
    throw Error("PCA-whitening of " + std::to_string(d_in) + " dims applied to a descriptor of " +
                std::to_string(x.size()));
  std::vector<double> centred(d_in);
  for (int i = 0; i < d_in; ++i) centred[i] = double(x[i]) - mean[i];
  std::vector<float> y(d_out);
  for (int r = 0; r < d_out; ++r) {
    const float* row = &projection[static_cast<size_t>(r) * d_in];
    double s = 0;
    for (int i = 0; i < d_in; ++i) s += row[i] * centred[i];
    y[r] = static_cast<float>(s);
  }
  L2Normalise(&y);
  return y;
}

void L2Normalise(std::vector<float>* v) {
  double n = 0;
  for (float x : *v) n += double(x) * x;
  n = std::sqrt(n);
  if (n > 0)
    for (float& x : *v) x = static_cast<float>(x / n);
}

// ------------------------------------------------------------- the pipeline

cv::Mat GlobalInputBlob(const cv::Mat& rgb, const GlobalOptions& o, double scale) {
  if (rgb.empty() || rgb.type() != CV_8UC3) throw Error("global descriptor: expected an 8-bit RGB image");
  double sx = 1, sy = 1;
  if (o.resize == "max_side") {
    const double s = std::min(1.0, o.max_side / static_cast<double>(std::max(rgb.rows, rgb.cols)));
    sx = sy = s;
  } else if (o.resize == "fixed") {
    sx = static_cast<double>(o.width) / rgb.cols;
    sy = static_cast<double>(o.height) / rgb.rows;
  }
  const int w = std::max(1, static_cast<int>(std::lround(rgb.cols * sx * scale)));
  const int h = std::max(1, static_cast<int>(std::lround(rgb.rows * sy * scale)));
  cv::Mat resized = rgb;
  if (w != rgb.cols || h != rgb.rows)
    cv::resize(rgb, resized, cv::Size(w, h), 0, 0,
               w * h < rgb.cols * rgb.rows ? cv::INTER_AREA : cv::INTER_LINEAR);
  cv::Mat ordered = resized;
  if (o.channel_order == "BGR") cv::cvtColor(resized, ordered, cv::COLOR_RGB2BGR);
  cv::Mat f;
  ordered.convertTo(f, CV_32FC3);
  cv::subtract(f, cv::Scalar(o.mean[0], o.mean[1], o.mean[2]), f);
  cv::divide(f, cv::Scalar(o.std[0], o.std[1], o.std[2]), f);
  return ToBlob(f);
}

GlobalDescriptor ExtractGlobal(const cv::Mat& rgb, const GlobalOptions& o, const PcaWhitening* pca) {
  cv::dnn::Net& net = ThreadNet(o.model);
  GlobalDescriptor g;
  std::vector<double> sum;
  for (double scale : o.scales) {
    const cv::Mat blob = GlobalInputBlob(rgb, o, scale);
    g.input_sizes.push_back(blob.size[3]);
    g.input_sizes.push_back(blob.size[2]);
    const auto start = std::chrono::steady_clock::now();
    cv::Mat out;
    try {
      net.setInput(blob, o.input);
      out = o.output.empty() ? net.forward() : net.forward(o.output);
    } catch (const cv::Exception& e) {
      throw InputError(o.model, 0, "model",
                       "the network failed on a " + std::to_string(blob.size[3]) + "x" +
                           std::to_string(blob.size[2]) + " input '" + o.input + "' (output '" +
                           o.output + "'): " + e.what());
    }
    g.network_seconds += SecondsSince(start);
    if (!out.isContinuous() || out.depth() != CV_32F || out.total() == 0)
      throw InputError(o.model, 0, "model", "output '" + o.output + "' is not a float32 tensor");
    std::vector<float> d(out.ptr<float>(), out.ptr<float>() + out.total());
    if (g.raw.empty()) g.raw = d;
    L2Normalise(&d);
    if (sum.empty()) sum.assign(d.size(), 0.0);
    if (sum.size() != d.size())
      throw InputError(o.model, 0, "model", "the descriptor size changes with the scale");
    for (size_t i = 0; i < d.size(); ++i) sum[i] += d[i];
  }
  g.values.assign(sum.begin(), sum.end());
  L2Normalise(&g.values);
  if (pca) g.values = pca->Apply(g.values);
  return g;
}

}  // namespace locforge::learned

#include "xfeat.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>

#include "locforge/error.h"
#include "locforge/kapture/features.h"
#include "onnx_net.h"

namespace locforge::learned {

namespace {

constexpr int kDim = 64;

// The authors' InterpolateSparse2d + grid_sample(align_corners = false): a
// position p (pixels of the full-resolution image of size `full`) normalised
// by full - 1, then unnormalised onto a map of size `size`, in float32 as
// torch does it.
float MapCoordinate(float p, int full, int size) {
  const float g = 2.0f * (p / static_cast<float>(full - 1)) - 1.0f;
  return ((g + 1.0f) * static_cast<float>(size) - 1.0f) / 2.0f;
}

// grid_sample 'nearest' (zero padding): rounds half to even, as nearbyint.
float SampleNearest(const float* map, int h, int w, float ix, float iy) {
  const int x = static_cast<int>(std::nearbyint(ix)), y = static_cast<int>(std::nearbyint(iy));
  if (x < 0 || x >= w || y < 0 || y >= h) return 0.0f;
  return map[static_cast<size_t>(y) * w + x];
}

// grid_sample 'bilinear' (zero padding).
float SampleBilinear(const float* map, int h, int w, float ix, float iy) {
  const int x0 = static_cast<int>(std::floor(ix)), y0 = static_cast<int>(std::floor(iy));
  const float tx = ix - static_cast<float>(x0), ty = iy - static_cast<float>(y0);
  auto at = [&](int x, int y) {
    return (x < 0 || x >= w || y < 0 || y >= h) ? 0.0f : map[static_cast<size_t>(y) * w + x];
  };
  return at(x0, y0) * (1 - tx) * (1 - ty) + at(x0 + 1, y0) * tx * (1 - ty) +
         at(x0, y0 + 1) * (1 - tx) * ty + at(x0 + 1, y0 + 1) * tx * ty;
}

// torch's cubic convolution coefficients (A = -0.75) at fraction t.
void CubicCoefficients(float t, float c[4]) {
  constexpr float A = -0.75f;
  auto near = [](float x) { return ((A + 2) * x - (A + 3)) * x * x + 1; };   // |x| <= 1
  auto far = [](float x) { return ((A * x - 5 * A) * x + 8 * A) * x - 4 * A; };  // 1 < |x| < 2
  c[0] = far(t + 1.0f);
  c[1] = near(t);
  c[2] = near(1.0f - t);
  c[3] = far(2.0f - t);
}

// grid_sample 'bicubic' (zero padding) of every channel of a C x h x w map.
void SampleBicubic(const float* map, int channels, int h, int w, float ix, float iy, float* out) {
  const float fx = std::floor(ix), fy = std::floor(iy);
  const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
  float cx[4], cy[4];
  CubicCoefficients(ix - fx, cx);
  CubicCoefficients(iy - fy, cy);
  const size_t plane = static_cast<size_t>(h) * w;
  for (int c = 0; c < channels; ++c) {
    const float* m = map + c * plane;
    float rows[4];
    for (int i = 0; i < 4; ++i) {
      const int y = y0 - 1 + i;
      float v[4];
      for (int j = 0; j < 4; ++j) {
        const int x = x0 - 1 + j;
        v[j] = (x < 0 || x >= w || y < 0 || y >= h) ? 0.0f : m[static_cast<size_t>(y) * w + x];
      }
      rows[i] = v[0] * cx[0] + v[1] * cx[1] + v[2] * cx[2] + v[3] * cx[3];
    }
    out[c] = rows[0] * cy[0] + rows[1] * cy[1] + rows[2] * cy[2] + rows[3] * cy[3];
  }
}

// F.normalize: x / max(|x|, 1e-12).
void Normalise(float* v, int n, size_t stride = 1) {
  double s = 0;
  for (int k = 0; k < n; ++k) s += static_cast<double>(v[k * stride]) * v[k * stride];
  const float norm = static_cast<float>(std::max(std::sqrt(s), 1e-12));
  for (int k = 0; k < n; ++k) v[k * stride] /= norm;
}

bool OutputsFollowContract(const std::vector<cv::Mat>& outputs, int h, int w) {
  if (outputs.size() != 3) return false;
  const int channels[3] = {kDim, 65, 1};
  for (int i = 0; i < 3; ++i) {
    const cv::Mat& m = outputs[i];
    if (m.dims != 4 || m.size[0] != 1 || m.size[1] != channels[i] || m.size[2] != h ||
        m.size[3] != w || m.type() != CV_32F || !m.isContinuous())
      return false;
  }
  return true;
}

}  // namespace

bool XfeatOptions::Check(std::string* why) const {
  if (model.empty()) {
    *why = "parameter 'model': the XFeat .onnx file is required (export_xfeat.py export)";
    return false;
  }
  if (!kapture::IsFeatureTypeName(type)) {
    *why = "parameter 'type': '" + type + "' is not a folder name";
    return false;
  }
  if (max_size != 0 && max_size < 32) {
    *why = "parameter 'max_size': " + std::to_string(max_size) +
           " is below 32, the network's smallest input (0 keeps the image's size)";
    return false;
  }
  return true;
}

namespace {

struct Candidate {
  int x, y;
  float score;
};

// The authors' preprocess_tensor: each side down to a multiple of 32
// (bilinear, align_corners = false, which INTER_LINEAR matches); with
// max_size, first the scale that brings the longer side under it (area).
// Grey = mean of R, G, B in [0, 1] (the network's first step in the authors'
// model; linear, so it commutes with the resize).
cv::Mat MakeNetworkInput(const cv::Mat& rgb, const XfeatOptions& o) {
  const int H = rgb.rows, W = rgb.cols;
  double s = 1.0;
  if (o.max_size > 0 && std::max(H, W) > o.max_size) s = static_cast<double>(o.max_size) / std::max(H, W);
  const int H32 = static_cast<int>(std::floor(H * s + 1e-9)) / 32 * 32;
  const int W32 = static_cast<int>(std::floor(W * s + 1e-9)) / 32 * 32;
  if (H32 < 32 || W32 < 32)
    throw InputError(o.model, 0, "max_size",
                     "a " + std::to_string(W) + "x" + std::to_string(H) +
                         " image gives a network input below 32x32");
  cv::Mat grey(H, W, CV_32F);
  for (int y = 0; y < H; ++y) {
    const uint8_t* p = rgb.ptr<uint8_t>(y);
    float* g = grey.ptr<float>(y);
    for (int x = 0; x < W; ++x)
      g[x] = (p[3 * x] / 255.0f + p[3 * x + 1] / 255.0f + p[3 * x + 2] / 255.0f) / 3.0f;
  }
  if (H32 != H || W32 != W) {
    cv::Mat resized;
    cv::resize(grey, resized, cv::Size(W32, H32), 0, 0, s < 1.0 ? cv::INTER_AREA : cv::INTER_LINEAR);
    grey = resized;
  }
  return grey;
}

// Runs the network on the H32 x W32 grey input; outputs descriptors,
// keypoint logits and reliability, checked against the contract.
std::vector<cv::Mat> RunNetwork(const std::string& model, cv::Mat& grey, double* seconds) {
  const int H32 = grey.rows, W32 = grey.cols;
  cv::dnn::Net& net = ThreadNet(model);
  const int blob_size[4] = {1, 1, H32, W32};
  net.setInput(cv::Mat(4, blob_size, CV_32F, grey.ptr<float>()), "image");
  static const std::vector<cv::String> kOutputs = {"descriptors", "keypoints", "reliability"};
  std::vector<cv::Mat> outputs;
  const auto start = std::chrono::steady_clock::now();
  net.forward(outputs, kOutputs);
  *seconds = SecondsSince(start);
  const int h = H32 / 8, w = W32 / 8;
  if (!OutputsFollowContract(outputs, h, w))
    throw InputError(model, 0, "model",
                     "outputs do not follow the XFeat contract (descriptors 1x64xhxw, keypoints "
                     "1x65xhxw, reliability 1x1xhxw with h x w = " +
                         std::to_string(h) + "x" + std::to_string(w) + " for a " +
                         std::to_string(W32) + "x" + std::to_string(H32) + " input)");
  return outputs;
}

// Keypoint logits (65 x h x w) -> softmax over 65 bins -> drop the dustbin
// -> an H32 x W32 heatmap.
cv::Mat Heatmap(const cv::Mat& keypoint_logits, int H32, int W32) {
  const int h = H32 / 8, w = W32 / 8;
  const size_t plane = static_cast<size_t>(h) * w;
  const float* logits = keypoint_logits.ptr<float>();
  cv::Mat heat(H32, W32, CV_32F);
  for (int cy = 0; cy < h; ++cy)
    for (int cx = 0; cx < w; ++cx) {
      const size_t cell = static_cast<size_t>(cy) * w + cx;
      float m = logits[cell];
      for (int k = 1; k < 65; ++k) m = std::max(m, logits[k * plane + cell]);
      float e[65], sum = 0;
      for (int k = 0; k < 65; ++k) sum += (e[k] = std::exp(logits[k * plane + cell] - m));
      for (int i = 0; i < 8; ++i)
        for (int j = 0; j < 8; ++j) heat.at<float>(cy * 8 + i, cx * 8 + j) = e[i * 8 + j] / sum;
    }
  return heat;
}

// 5x5 non-maximum suppression (max pool of stride 1, the window clipped at
// the border), above the threshold; raster order as torch's nonzero; scored
// by heat x reliability, best first, at most top_k with a positive score.
std::vector<Candidate> SelectKeypoints(const cv::Mat& heat, const float* reliability, const XfeatOptions& o) {
  const int H32 = heat.rows, W32 = heat.cols, h = H32 / 8, w = W32 / 8;
  cv::Mat local_max;
  cv::dilate(heat, local_max, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)), cv::Point(-1, -1), 1,
             cv::BORDER_CONSTANT, cv::Scalar(-1e30));
  std::vector<Candidate> candidates;
  const float threshold = static_cast<float>(o.detection_threshold);
  for (int y = 0; y < H32; ++y) {
    const float* hv = heat.ptr<float>(y);
    const float* mv = local_max.ptr<float>(y);
    for (int x = 0; x < W32; ++x) {
      if (!(hv[x] > threshold) || hv[x] != mv[x]) continue;
      const float px = static_cast<float>(x), py = static_cast<float>(y);
      float score = SampleNearest(heat.ptr<float>(), H32, W32, MapCoordinate(px, W32, W32),
                                  MapCoordinate(py, H32, H32)) *
                    SampleBilinear(reliability, h, w, MapCoordinate(px, W32, w), MapCoordinate(py, H32, h));
      if (x == 0 && y == 0) score = -1;  // the authors' padding marker
      candidates.push_back({x, y, score});
    }
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
  if (candidates.size() > static_cast<size_t>(o.top_k)) candidates.resize(o.top_k);
  while (!candidates.empty() && !(candidates.back().score > 0)) candidates.pop_back();
  return candidates;
}

}  // namespace

XfeatFeatures ExtractXfeat(const cv::Mat& rgb, const XfeatOptions& o) {
  if (rgb.empty() || rgb.type() != CV_8UC3) throw Error("ExtractXfeat: expected an 8-bit RGB image");
  const int H = rgb.rows, W = rgb.cols;
  cv::Mat grey = MakeNetworkInput(rgb, o);
  const int H32 = grey.rows, W32 = grey.cols, h = H32 / 8, w = W32 / 8;
  XfeatFeatures f;
  const std::vector<cv::Mat> outputs = RunNetwork(o.model, grey, &f.network_seconds);
  f.network_width = W32;
  f.network_height = H32;
  const std::vector<Candidate> candidates =
      SelectKeypoints(Heatmap(outputs[1], H32, W32), outputs[2].ptr<float>(), o);

  // Descriptors: the dense map normalised per pixel, bicubic at each keypoint,
  // normalised again.
  const size_t plane = static_cast<size_t>(h) * w;
  cv::Mat dense = outputs[0].clone();
  float* d = dense.ptr<float>();
  for (size_t p = 0; p < plane; ++p) Normalise(d + p, kDim, plane);
  const float rw = static_cast<float>(W) / W32, rh = static_cast<float>(H) / H32;
  const size_t n = candidates.size();
  f.raw_keypoints.reserve(2 * n);
  f.keypoints.reserve(2 * n);
  f.scores.reserve(n);
  f.descriptors.resize(kDim * n);
  for (size_t i = 0; i < n; ++i) {
    const Candidate& c = candidates[i];
    const float px = static_cast<float>(c.x), py = static_cast<float>(c.y);
    float* out = &f.descriptors[kDim * i];
    SampleBicubic(d, kDim, h, w, MapCoordinate(px, W32, w), MapCoordinate(py, H32, h), out);
    Normalise(out, kDim);
    f.raw_keypoints.insert(f.raw_keypoints.end(), {px * rw, py * rh});
    f.keypoints.insert(f.keypoints.end(), {(px + 0.5f) * rw, (py + 0.5f) * rh});
    f.scores.push_back(c.score);
  }
  return f;
}

}  // namespace locforge::learned

#include "alike.h"

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

constexpr int kRadius = 2;             // all four authors' configurations
constexpr float kTemperature = 0.1f;  // DKD's tuned temperature

// 5x5 max pool, stride 1, the window clipped at the border (torch pads -inf).
cv::Mat MaxPool(const cv::Mat& m) {
  cv::Mat out;
  cv::dilate(m, out, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * kRadius + 1, 2 * kRadius + 1)),
             cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(-1e30));
  return out;
}

// The authors' simple_nms (SuperPoint's): maxima, then two rounds that
// suppress the neighbourhoods of maxima and add the new maxima outside them.
cv::Mat SimpleNms(const cv::Mat& scores) {
  cv::Mat max_mask = scores == MaxPool(scores);  // 8U: 255 / 0
  const cv::Mat zeros = cv::Mat::zeros(scores.size(), CV_32F);
  for (int round = 0; round < 2; ++round) {
    cv::Mat mask_f;
    max_mask.convertTo(mask_f, CV_32F, 1.0 / 255);
    const cv::Mat supp_mask = MaxPool(mask_f) > 0;
    cv::Mat supp_scores = scores.clone();
    supp_scores.setTo(0, supp_mask);
    const cv::Mat new_max_mask = supp_scores == MaxPool(supp_scores);
    max_mask |= new_max_mask & ~supp_mask;
  }
  cv::Mat nms = zeros.clone();
  scores.copyTo(nms, max_mask);
  return nms;
}

// grid_sample 'bilinear', align_corners = true, zero padding, at pixel
// position (x, y) of an h x w map with row stride `stride`.
float Bilinear(const float* map, int h, int w, size_t stride, float x, float y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const float tx = x - static_cast<float>(x0), ty = y - static_cast<float>(y0);
  auto at = [&](int xx, int yy) {
    return (xx < 0 || xx >= w || yy < 0 || yy >= h) ? 0.0f : map[static_cast<size_t>(yy) * stride + xx];
  };
  return at(x0, y0) * (1 - tx) * (1 - ty) + at(x0 + 1, y0) * tx * (1 - ty) +
         at(x0, y0 + 1) * (1 - tx) * ty + at(x0 + 1, y0 + 1) * tx * ty;
}

bool OutputsFollowContract(const std::vector<cv::Mat>& outputs, int h, int w) {
  if (outputs.size() != 2) return false;
  for (const cv::Mat& m : outputs)
    if (m.dims != 4 || m.size[0] != 1 || m.size[2] != h || m.size[3] != w || m.type() != CV_32F ||
        !m.isContinuous())
      return false;
  return outputs[0].size[1] == 1 && outputs[1].size[1] >= 1;
}

std::vector<cv::Mat> RunNetwork(const std::string& model, const cv::Mat& blob, double* seconds) {
  cv::dnn::Net& net = ThreadNet(model);
  net.setInput(blob, "image");
  static const std::vector<cv::String> kOutputs = {"scores", "descriptors"};
  std::vector<cv::Mat> outputs;
  const auto start = std::chrono::steady_clock::now();
  net.forward(outputs, kOutputs);
  if (seconds) *seconds = SecondsSince(start);
  if (!OutputsFollowContract(outputs, blob.size[2], blob.size[3]))
    throw InputError(model, 0, "model",
                     "outputs do not follow the ALIKE contract (scores 1x1xHxW, descriptors "
                     "1xDxHxW for a 1x3xHxW input, " +
                         std::to_string(blob.size[3]) + "x" + std::to_string(blob.size[2]) + ")");
  return outputs;
}

}  // namespace

bool AlikeOptions::Check(std::string* why) const {
  if (model.empty()) {
    *why = "parameter 'model': the ALIKE .onnx file is required (export_alike.py export)";
    return false;
  }
  if (!kapture::IsFeatureTypeName(type)) {
    *why = "parameter 'type': '" + type + "' is not a folder name";
    return false;
  }
  if (max_size != 0 && max_size < 2 * kRadius + 4) {
    *why = "parameter 'max_size': " + std::to_string(max_size) + " leaves no pixel inside the border";
    return false;
  }
  return true;
}

int AlikeDescriptorDim(const std::string& model) {
  const int size[4] = {1, 3, 32, 32};
  return RunNetwork(model, cv::Mat(4, size, CV_32F, cv::Scalar(0)), nullptr)[1].size[1];
}

namespace {

// A sub-pixel keypoint in the authors' normalised coordinates ([-1, 1]).
struct Keypoint {
  float x, y, score;
};

// The optional downscale (the authors' image_size_max).
cv::Mat ResizeForNetwork(const cv::Mat& input, const AlikeOptions& o) {
  cv::Mat rgb = input;
  const int longer = std::max(input.rows, input.cols);
  if (o.max_size > 0 && longer > o.max_size) {
    const double ratio = static_cast<double>(o.max_size) / longer;
    cv::resize(input, rgb, cv::Size(), ratio, ratio, cv::INTER_LINEAR);
  }
  if (rgb.rows <= 2 * kRadius + 1 || rgb.cols <= 2 * kRadius + 1)
    throw InputError(o.model, 0, "max_size",
                     "a " + std::to_string(rgb.cols) + "x" + std::to_string(rgb.rows) +
                         " network input leaves no pixel inside the border");
  return rgb;
}

// 1x3xh32xw32, RGB / 255, zero padding at the bottom and right.
cv::Mat MakeBlob(const cv::Mat& rgb) {
  const int h = rgb.rows, w = rgb.cols;
  const int h32 = (h + 31) / 32 * 32, w32 = (w + 31) / 32 * 32;
  const int size[4] = {1, 3, h32, w32};
  cv::Mat blob(4, size, CV_32F, cv::Scalar(0));
  float* b = blob.ptr<float>();
  const size_t plane32 = static_cast<size_t>(h32) * w32;
  for (int y = 0; y < h; ++y) {
    const uint8_t* p = rgb.ptr<uint8_t>(y);
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) b[c * plane32 + static_cast<size_t>(y) * w32 + x] = p[3 * x + c] / 255.0f;
  }
  return blob;
}

// NMS peaks inside the border, as indices y * w + x: the top_k best, or those
// over the threshold (the map's mean when none passes), at most n_limit.
std::vector<int> SelectPeaks(const cv::Mat& scores, const AlikeOptions& o) {
  const int h = scores.rows, w = scores.cols;
  cv::Mat nms = SimpleNms(scores);
  nms.rowRange(0, kRadius + 1).setTo(0);
  nms.colRange(0, kRadius + 1).setTo(0);
  nms.rowRange(h - kRadius, h).setTo(0);
  nms.colRange(w - kRadius, w).setTo(0);
  std::vector<int> indices;
  if (o.top_k > 0) {
    std::vector<int> all(static_cast<size_t>(h) * w);
    std::iota(all.begin(), all.end(), 0);
    const size_t k = std::min(all.size(), static_cast<size_t>(o.top_k));
    const float* v = nms.ptr<float>();
    std::partial_sort(all.begin(), all.begin() + k, all.end(), [&](int a, int c) { return v[a] > v[c]; });
    indices.assign(all.begin(), all.begin() + k);
    return indices;
  }
  auto select = [&](float threshold) {
    indices.clear();
    for (int y = 0; y < h; ++y) {
      const float* v = nms.ptr<float>(y);
      for (int x = 0; x < w; ++x)
        if (v[x] > threshold) indices.push_back(y * w + x);
    }
  };
  select(static_cast<float>(o.scores_threshold));
  if (indices.empty()) select(static_cast<float>(cv::mean(scores)[0]));
  if (indices.size() > static_cast<size_t>(o.n_limit)) {
    std::stable_sort(indices.begin(), indices.end(), [&](int a, int c) {
      return scores.at<float>(a / w, a % w) > scores.at<float>(c / w, c % w);
    });
    indices.resize(o.n_limit);
  }
  return indices;
}

// DKD's soft-argmax in the 5x5 window (zero padding), the score bilinearly
// sampled at the refined position. `scores` is a view with row stride `stride`.
Keypoint RefineSoftArgmax(const cv::Mat& scores, size_t stride, int index) {
  const int h = scores.rows, w = scores.cols;
  const int cx = index % w, cy = index / w;
  float patch[25], m = -1e30f;
  for (int dy = -kRadius, k = 0; dy <= kRadius; ++dy)
    for (int dx = -kRadius; dx <= kRadius; ++dx, ++k) {
      const int x = cx + dx, y = cy + dy;
      patch[k] = (x < 0 || x >= w || y < 0 || y >= h) ? 0.0f : scores.at<float>(y, x);
      m = std::max(m, patch[k]);
    }
  float sum = 0, sx = 0, sy = 0;
  for (int dy = -kRadius, k = 0; dy <= kRadius; ++dy)
    for (int dx = -kRadius; dx <= kRadius; ++dx, ++k) {
      const float e = std::exp((patch[k] - m) / kTemperature);
      sum += e, sx += e * dx, sy += e * dy;
    }
  // The authors normalise to [-1, 1] by (w - 1, h - 1) and sample with
  // align_corners = true, which maps back to the same pixel position.
  const float x = static_cast<float>(cx) + sx / sum, y = static_cast<float>(cy) + sy / sum;
  const float nx = x / static_cast<float>(w - 1) * 2 - 1, ny = y / static_cast<float>(h - 1) * 2 - 1;
  const float px = (nx + 1) / 2 * static_cast<float>(w - 1), py = (ny + 1) / 2 * static_cast<float>(h - 1);
  return {nx, ny, Bilinear(scores.ptr<float>(), h, w, stride, px, py)};
}

// The per-pixel L2-normalised descriptor map (dim planes of `plane` floats,
// row stride `stride`) bilinearly sampled at pixel (px, py), L2-normalised again.
void SampleDescriptor(const float* desc, int dim, size_t plane, size_t stride, int h, int w, float px, float py,
                      float* out) {
  const int x0 = static_cast<int>(std::floor(px)), y0 = static_cast<int>(std::floor(py));
  const float tx = px - static_cast<float>(x0), ty = py - static_cast<float>(y0);
  const float weights[4] = {(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty};
  for (int t = 0; t < 4; ++t) {
    const int x = x0 + (t & 1), y = y0 + (t >> 1);
    if (x < 0 || x >= w || y < 0 || y >= h) continue;
    const float* d = desc + static_cast<size_t>(y) * stride + x;
    double norm = 0;
    for (int c = 0; c < dim; ++c) norm += static_cast<double>(d[c * plane]) * d[c * plane];
    const float scale = weights[t] / static_cast<float>(std::max(std::sqrt(norm), 1e-12));
    for (int c = 0; c < dim; ++c) out[c] += d[c * plane] * scale;
  }
  double norm = 0;
  for (int c = 0; c < dim; ++c) norm += static_cast<double>(out[c]) * out[c];
  const float inv = 1.0f / static_cast<float>(std::max(std::sqrt(norm), 1e-12));
  for (int c = 0; c < dim; ++c) out[c] *= inv;
}

}  // namespace

AlikeFeatures ExtractAlike(const cv::Mat& input, const AlikeOptions& o) {
  if (input.empty() || input.type() != CV_8UC3) throw Error("ExtractAlike: expected an 8-bit RGB image");
  const int H = input.rows, W = input.cols;
  const cv::Mat rgb = ResizeForNetwork(input, o);
  const int h = rgb.rows, w = rgb.cols;
  const cv::Mat blob = MakeBlob(rgb);
  const int w32 = blob.size[3];
  const size_t plane = static_cast<size_t>(blob.size[2]) * w32;

  AlikeFeatures f;
  const std::vector<cv::Mat> outputs = RunNetwork(o.model, blob, &f.network_seconds);
  const int dim = f.dim = outputs[1].size[1];
  // The maps cropped to the image (views with row stride w32).
  const cv::Mat scores(h, w, CV_32F, const_cast<float*>(outputs[0].ptr<float>()), w32 * sizeof(float));
  const float* desc = outputs[1].ptr<float>();

  std::vector<Keypoint> keypoints;
  for (int index : SelectPeaks(scores, o)) keypoints.push_back(RefineSoftArgmax(scores, w32, index));
  std::vector<size_t> order(keypoints.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t c) { return keypoints[a].score > keypoints[c].score; });

  const size_t n = order.size();
  f.raw_keypoints.reserve(2 * n);
  f.keypoints.reserve(2 * n);
  f.scores.reserve(n);
  f.descriptors.assign(static_cast<size_t>(dim) * n, 0.0f);
  for (size_t i = 0; i < n; ++i) {
    const Keypoint& k = keypoints[order[i]];
    const float px = (k.x + 1) / 2 * static_cast<float>(w - 1), py = (k.y + 1) / 2 * static_cast<float>(h - 1);
    SampleDescriptor(desc, dim, plane, w32, h, w, px, py, &f.descriptors[static_cast<size_t>(dim) * i]);
    // Back to the input image: the authors' (k + 1) / 2 * (W - 1, H - 1).
    const float rx = (k.x + 1) / 2 * static_cast<float>(W - 1), ry = (k.y + 1) / 2 * static_cast<float>(H - 1);
    f.raw_keypoints.insert(f.raw_keypoints.end(), {rx, ry});
    f.keypoints.insert(f.keypoints.end(), {rx + 0.5f, ry + 0.5f});
    f.scores.push_back(k.score);
  }
  return f;
}

}  // namespace locforge::learned

#include "d2net.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>

#include "locforge/error.h"
#include "onnx_net.h"
#include "locforge/kapture/features.h"

namespace locforge::learned {

namespace {

// C x h x w float tensor, row-major.
struct Tensor {
  int c = 0, h = 0, w = 0;
  std::vector<float> v;
  float& at(int k, int i, int j) { return v[(static_cast<size_t>(k) * h + i) * w + j]; }
  float at(int k, int i, int j) const { return v[(static_cast<size_t>(k) * h + i) * w + j]; }
  // Zero outside (conv2d with padding = 1).
  float zero_padded(int k, int i, int j) const {
    return i < 0 || j < 0 || i >= h || j >= w ? 0.f : at(k, i, j);
  }
};

// F.interpolate(x, size=(h, w), mode='bilinear', align_corners=True).
Tensor ResizeAlignCorners(const Tensor& x, int h, int w) {
  Tensor y{x.c, h, w, std::vector<float>(static_cast<size_t>(x.c) * h * w)};
  const double ry = h > 1 ? double(x.h - 1) / (h - 1) : 0, rx = w > 1 ? double(x.w - 1) / (w - 1) : 0;
  for (int i = 0; i < h; ++i) {
    const double sy = i * ry;
    const int y0 = std::min(static_cast<int>(sy), x.h - 1), y1 = std::min(y0 + 1, x.h - 1);
    const float fy = static_cast<float>(sy - y0);
    for (int j = 0; j < w; ++j) {
      const double sx = j * rx;
      const int x0 = std::min(static_cast<int>(sx), x.w - 1), x1 = std::min(x0 + 1, x.w - 1);
      const float fx = static_cast<float>(sx - x0);
      for (int k = 0; k < x.c; ++k) {
        const float top = (1 - fx) * x.at(k, y0, x0) + fx * x.at(k, y0, x1);
        const float bottom = (1 - fx) * x.at(k, y1, x0) + fx * x.at(k, y1, x1);
        y.at(k, i, j) = (1 - fy) * top + fy * bottom;
      }
    }
  }
  return y;
}

// Derivatives of D^k at (i, j) with the authors' 3x3 filters (zero padding):
// di = (D[i+1] - D[i-1]) / 2, dii = D[i+1] - 2 D + D[i-1],
// dij = (D[i-1,j-1] - D[i-1,j+1] - D[i+1,j-1] + D[i+1,j+1]) / 4.
struct Derivatives {
  float di, dj, dii, djj, dij;
};
Derivatives At(const Tensor& d, int k, int i, int j) {
  const float c = d.at(k, i, j);
  const float up = d.zero_padded(k, i - 1, j), down = d.zero_padded(k, i + 1, j);
  const float left = d.zero_padded(k, i, j - 1), right = d.zero_padded(k, i, j + 1);
  Derivatives r;
  r.di = 0.5f * (down - up);
  r.dj = 0.5f * (right - left);
  r.dii = up - 2 * c + down;
  r.djj = left - 2 * c + right;
  r.dij = 0.25f * (d.zero_padded(k, i - 1, j - 1) - d.zero_padded(k, i - 1, j + 1) -
                   d.zero_padded(k, i + 1, j - 1) + d.zero_padded(k, i + 1, j + 1));
  return r;
}

// Soft detection score map of one level (paper eq. 3-5, SoftDetectionModule):
// h x w, summing to 1.
std::vector<float> SoftScores(const Tensor& d) {
  const size_t hw = static_cast<size_t>(d.h) * d.w;
  float global_max = 0;
  for (float x : d.v) global_max = std::max(global_max, std::max(x, 0.f));
  std::vector<float> e(d.v.size());
  for (size_t n = 0; n < d.v.size(); ++n)
    e[n] = std::exp(global_max > 0 ? std::max(d.v[n], 0.f) / global_max : 0.f);
  std::vector<float> depth_max(hw, 0.f);
  for (int k = 0; k < d.c; ++k)
    for (size_t p = 0; p < hw; ++p) depth_max[p] = std::max(depth_max[p], std::max(d.v[k * hw + p], 0.f));
  std::vector<float> score(hw, 0.f);
  for (int k = 0; k < d.c; ++k) {
    const float* ek = &e[k * hw];
    for (int i = 0; i < d.h; ++i)
      for (int j = 0; j < d.w; ++j) {
        // alpha: exp / sum of the 3x3 window, the padding counting exp = 1.
        float sum = 0;
        for (int di = -1; di <= 1; ++di)
          for (int dj = -1; dj <= 1; ++dj) {
            const int y = i + di, x = j + dj;
            sum += (y < 0 || x < 0 || y >= d.h || x >= d.w) ? 1.f : ek[y * d.w + x];
          }
        const size_t p = static_cast<size_t>(i) * d.w + j;
        const float alpha = ek[p] / sum;
        // beta: D^k / max_t D^t (0 where every channel is 0).
        const float beta = depth_max[p] > 0 ? std::max(d.v[k * hw + p], 0.f) / depth_max[p] : 0.f;
        score[p] = std::max(score[p], alpha * beta);
      }
  }
  const double total = std::accumulate(score.begin(), score.end(), 0.0);
  if (total > 0)
    for (float& s : score) s = static_cast<float>(s / total);
  return score;
}

struct Detection {
  float x, y, inv_scale, score;  // raw convention, in the resized image
  std::vector<float> descriptor;
};

// The detections of one level: D^k_ij channel maximum, 3x3 local maximum,
// not an edge, not banned; refined and described (process_multiscale).
void DetectLevel(const Tensor& d, const std::vector<uint8_t>& banned, double edge_threshold,
                 int level_index, double scale, double fy, double fx, bool soft,
                 std::vector<Detection>* out, std::vector<uint8_t>* detected_any) {
  const size_t hw = static_cast<size_t>(d.h) * d.w;
  const float threshold = static_cast<float>((edge_threshold + 1) * (edge_threshold + 1) / edge_threshold);
  std::vector<float> depth_max(hw, -std::numeric_limits<float>::infinity());
  for (int k = 0; k < d.c; ++k)
    for (size_t p = 0; p < hw; ++p) depth_max[p] = std::max(depth_max[p], d.v[k * hw + p]);
  std::vector<float> soft_scores;
  if (soft) soft_scores = SoftScores(d);
  detected_any->assign(hw, 0);
  // torch.nonzero order: channel, then row, then column.
  for (int k = 0; k < d.c; ++k) {
    for (int i = 0; i < d.h; ++i) {
      for (int j = 0; j < d.w; ++j) {
        const size_t p = static_cast<size_t>(i) * d.w + j;
        const float v = d.at(k, i, j);
        if (v != depth_max[p] || banned[p]) continue;
        bool local_max = true;  // max_pool2d(3, stride 1, padding 1): padding never wins
        for (int di = -1; di <= 1 && local_max; ++di)
          for (int dj = -1; dj <= 1; ++dj) {
            const int y = i + di, x = j + dj;
            if (y < 0 || x < 0 || y >= d.h || x >= d.w) continue;
            if (d.at(k, y, x) > v) {
              local_max = false;
              break;
            }
          }
        if (!local_max) continue;
        const Derivatives g = At(d, k, i, j);
        const float det = g.dii * g.djj - g.dij * g.dij;
        const float tr = g.dii + g.djj;
        if (!(det > 0) || !(tr * tr / det <= threshold)) continue;
        (*detected_any)[p] = 1;
        // One Newton step: -H^-1 grad (HandcraftedLocalizationModule).
        const float step_i = -((g.djj / det) * g.di + (-g.dij / det) * g.dj);
        const float step_j = -((-g.dij / det) * g.di + (g.dii / det) * g.dj);
        if (!(std::abs(step_i) < 0.5f && std::abs(step_j) < 0.5f)) continue;
        const float pi = i + step_i, pj = j + step_j;
        // interpolate_dense_features: the four neighbours must be inside.
        const int i0 = static_cast<int>(std::floor(pi)), j0 = static_cast<int>(std::floor(pj));
        const int i1 = static_cast<int>(std::ceil(pi)), j1 = static_cast<int>(std::ceil(pj));
        if (i0 < 0 || j0 < 0 || i1 >= d.h || j1 >= d.w) continue;
        const float ti = pi - i0, tj = pj - j0;
        Detection det_out;
        det_out.descriptor.resize(d.c);
        double norm = 0;
        for (int c = 0; c < d.c; ++c) {
          const float value = (1 - ti) * (1 - tj) * d.at(c, i0, j0) + (1 - ti) * tj * d.at(c, i0, j1) +
                              ti * (1 - tj) * d.at(c, i1, j0) + ti * tj * d.at(c, i1, j1);
          det_out.descriptor[c] = value;
          norm += double(value) * value;
        }
        norm = std::max(std::sqrt(norm), 1e-12);
        for (float& value : det_out.descriptor) value = static_cast<float>(value / norm);
        // upscale_positions(pos, 2): p -> 2 p + 0.5, twice = 4 p + 1.5.
        det_out.y = static_cast<float>((4 * pi + 1.5) * fy);
        det_out.x = static_cast<float>((4 * pj + 1.5) * fx);
        det_out.inv_scale = static_cast<float>(1.0 / scale);
        det_out.score = soft ? soft_scores[p] : v / static_cast<float>(level_index + 1);
        out->push_back(std::move(det_out));
      }
    }
  }
}

}  // namespace

bool D2netOptions::Check(std::string* why) const {
  if (model.empty()) {
    *why = "parameter 'model': the D2-Net .onnx file is required";
    return false;
  }
  if (!kapture::IsFeatureTypeName(type)) {
    *why = "parameter 'type': '" + type + "' is not a folder name";
    return false;
  }
  if (scales.empty()) {
    *why = "parameter 'scales': give at least one scale";
    return false;
  }
  if (mean.size() != 3) {
    *why = "parameter 'mean': give 3 values (B, G, R)";
    return false;
  }
  return true;
}

namespace {

// extract_features.py: max_edge, then max_sum_edges (imresize truncates sizes).
cv::Mat ResizeForNetwork(const cv::Mat& rgb, const D2netOptions& o) {
  cv::Mat image = rgb;
  auto shrink = [&](double f) {
    cv::Mat r;
    cv::resize(image, r, cv::Size(static_cast<int>(image.cols * f), static_cast<int>(image.rows * f)), 0, 0,
               cv::INTER_LINEAR);
    image = r;
  };
  if (std::max(image.rows, image.cols) > o.max_edge) shrink(double(o.max_edge) / std::max(image.rows, image.cols));
  if (image.rows + image.cols > o.max_sum_edges) shrink(double(o.max_sum_edges) / (image.rows + image.cols));
  return image;
}

// Caffe preprocessing: BGR, mean-subtracted, as a 3 x H x W tensor.
Tensor CaffeInput(const cv::Mat& image, const std::vector<double>& mean) {
  Tensor base{3, image.rows, image.cols, {}};
  cv::Mat bgr, f;
  cv::cvtColor(image, bgr, cv::COLOR_RGB2BGR);
  bgr.convertTo(f, CV_32FC3);
  cv::subtract(f, cv::Scalar(mean[0], mean[1], mean[2]), f);
  const cv::Mat blob = ToBlob(f);
  base.v.assign(blob.ptr<float>(), blob.ptr<float>() + blob.total());
  return base;
}

// The dense features of one pyramid level (C x h x w), timed.
Tensor RunNetwork(cv::dnn::Net& net, const Tensor& input, const D2netOptions& o, double* network_seconds) {
  const int sizes[4] = {1, 3, input.h, input.w};
  cv::Mat blob(4, sizes, CV_32F, const_cast<float*>(input.v.data()));
  const auto start = std::chrono::steady_clock::now();
  cv::Mat f;
  try {
    net.setInput(blob, o.input);
    f = net.forward(o.output);
  } catch (const cv::Exception& e) {
    throw InputError(o.model, 0, "model", "the network failed on a " + std::to_string(input.w) + "x" +
                                              std::to_string(input.h) + " input: " + e.what());
  }
  *network_seconds += SecondsSince(start);
  if (f.dims != 4 || f.size[0] != 1 || f.depth() != CV_32F)
    throw InputError(o.model, 0, "model", "output '" + o.output + "' is not 1 x C x h x w float32");
  return Tensor{f.size[1], f.size[2], f.size[3], std::vector<float>(f.ptr<float>(), f.ptr<float>() + f.total())};
}

// banned = F.interpolate(banned, size=(h, w)) (mode 'nearest').
std::vector<uint8_t> ResampleNearest(const std::vector<uint8_t>& banned, int banned_h, int banned_w, int h, int w) {
  std::vector<uint8_t> out(static_cast<size_t>(h) * w, 0);
  if (banned.empty()) return out;
  const float ry = float(banned_h) / h, rx = float(banned_w) / w;
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const int si = std::min(static_cast<int>(std::floor(i * ry)), banned_h - 1);
      const int sj = std::min(static_cast<int>(std::floor(j * rx)), banned_w - 1);
      out[static_cast<size_t>(i) * w + j] = banned[static_cast<size_t>(si) * banned_w + sj];
    }
  return out;
}

// The best top_k detections (all when 0), in the original image's pixels.
void KeepBest(const std::vector<Detection>& all, int top_k, double fact_i, double fact_j, D2netFeatures* out) {
  std::vector<size_t> order(all.size());
  std::iota(order.begin(), order.end(), 0);
  if (top_k > 0) {
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return all[a].score > all[b].score; });
    if (order.size() > static_cast<size_t>(top_k)) order.resize(top_k);
  }
  for (size_t n : order) {
    const Detection& det = all[n];
    const float x = static_cast<float>(det.x * fact_j), y = static_cast<float>(det.y * fact_i);
    out->raw_keypoints.insert(out->raw_keypoints.end(), {x, y, det.inv_scale});
    out->keypoints.insert(out->keypoints.end(), {x + 0.5f, y + 0.5f, det.inv_scale});
    out->descriptors.insert(out->descriptors.end(), det.descriptor.begin(), det.descriptor.end());
    out->scores.push_back(det.score);
  }
}

}  // namespace

// The multi-scale pyramid of extract_features.py: each level's features plus
// the coarser level's upsampled, detections banned where a coarser level
// already detected.
D2netFeatures ExtractD2net(const cv::Mat& rgb, const D2netOptions& o) {
  if (rgb.empty() || rgb.type() != CV_8UC3) throw Error("ExtractD2net: expected an 8-bit RGB image");
  cv::dnn::Net& net = ThreadNet(o.model);
  const cv::Mat image = ResizeForNetwork(rgb, o);
  const double fact_i = double(rgb.rows) / image.rows, fact_j = double(rgb.cols) / image.cols;
  const Tensor base = CaffeInput(image, o.mean);

  D2netFeatures out;
  std::vector<Detection> all;
  Tensor previous;
  std::vector<uint8_t> banned;
  int banned_h = 0, banned_w = 0;
  for (size_t level = 0; level < o.scales.size(); ++level) {
    const double scale = o.scales[level];
    const int h_level = static_cast<int>(std::floor(base.h * scale));
    const int w_level = static_cast<int>(std::floor(base.w * scale));
    if (h_level < 8 || w_level < 8) continue;
    Tensor d = RunNetwork(net, scale == 1.0 ? base : ResizeAlignCorners(base, h_level, w_level), o,
                          &out.network_seconds);
    if (level > 0 && !previous.v.empty()) {
      if (previous.c != d.c) throw InputError(o.model, 0, "model", "channel count changes with the scale");
      const Tensor up = ResizeAlignCorners(previous, d.h, d.w);
      for (size_t n = 0; n < d.v.size(); ++n) d.v[n] += up.v[n];
    }
    std::vector<uint8_t> level_banned = ResampleNearest(banned, banned_h, banned_w, d.h, d.w);
    std::vector<uint8_t> detected;
    DetectLevel(d, level_banned, o.edge_threshold, static_cast<int>(level), scale,
                double(base.h) / h_level, double(base.w) / w_level, o.score == "soft", &all, &detected);
    for (size_t p = 0; p < detected.size(); ++p) level_banned[p] = level_banned[p] || detected[p];
    banned = std::move(level_banned);
    banned_h = d.h, banned_w = d.w;
    out.channels = d.c;
    ++out.levels;
    previous = std::move(d);
  }
  KeepBest(all, o.top_k, fact_i, fact_j, &out);
  return out;
}

}  // namespace locforge::learned

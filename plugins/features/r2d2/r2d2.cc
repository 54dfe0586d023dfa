#include "r2d2.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>

#include "locforge/error.h"
#include "locforge/kapture/features.h"
#include "onnx_net.h"

namespace locforge::learned {

namespace {

// The authors' loop compares scales with a 0.001 slack, so that levels that
// should land exactly on a bound (e.g. 0.5 after four divisions by 2^0.25)
// are not lost to rounding.
constexpr double kScaleSlack = 0.001;
constexpr double kScaleFactor = 1.189207115002721;  // 2^0.25

// (pixel / 255 - mean) / std per RGB channel, float32 HxWx3.
cv::Mat Normalise(const cv::Mat& rgb) {
  static const float kMean[3] = {0.485f, 0.456f, 0.406f};
  static const float kStd[3] = {0.229f, 0.224f, 0.225f};
  cv::Mat f;
  rgb.convertTo(f, CV_32FC3, 1.0 / 255.0);
  cv::subtract(f, cv::Scalar(kMean[0], kMean[1], kMean[2]), f);
  cv::divide(f, cv::Scalar(kStd[0], kStd[1], kStd[2]), f);
  return f;
}

struct Candidate {
  float x, y, scale;     // raw convention
  float sdk_x, sdk_y;    // SDK convention
  float score;
};

// Keypoints of one pyramid level: 3x3 maxima of repeatability (a max pool of
// stride 1, padding 1) above both thresholds. The level's input image is
// level_w x level_h; the maps may be a pixel smaller (see OutputsFollowContract)
// and, as in the authors' extract.py (x * W / nw with nw the level's input
// width), positions scale with the input size, not the map size.
// Descriptors are copied out at once (network outputs share its buffers).
void DetectAtLevel(const cv::Mat& descriptors, const cv::Mat& reliability,
                   const cv::Mat& repeatability, double s, int level_w, int level_h, int W,
                   int H, const R2d2Options& o, std::vector<Candidate>* out,
                   std::vector<float>* out_descriptors) {
  const int h = repeatability.size[2], w = repeatability.size[3];
  const float* rep = repeatability.ptr<float>();
  const float* rel = reliability.ptr<float>();
  const float* desc = descriptors.ptr<float>();
  const float fx = static_cast<float>(W) / level_w, fy = static_cast<float>(H) / level_h;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float r = rep[y * w + x];
      if (r < o.repeatability_threshold || rel[y * w + x] < o.reliability_threshold) continue;
      bool is_max = true;
      for (int dy = -1; dy <= 1 && is_max; ++dy) {
        const int yy = y + dy;
        if (yy < 0 || yy >= h) continue;
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx;
          if (xx < 0 || xx >= w) continue;
          if (rep[yy * w + xx] > r) {
            is_max = false;
            break;
          }
        }
      }
      if (!is_max) continue;
      Candidate c;
      c.x = static_cast<float>(x) * fx;
      c.y = static_cast<float>(y) * fy;
      c.sdk_x = (static_cast<float>(x) + 0.5f) * fx;
      c.sdk_y = (static_cast<float>(y) + 0.5f) * fy;
      c.scale = static_cast<float>(32.0 / s);
      c.score = rel[y * w + x] * r;
      out->push_back(c);
      const float* d = desc + (y * w + x);
      for (int k = 0; k < 128; ++k) out_descriptors->push_back(d[static_cast<size_t>(k) * h * w]);
    }
  }
}

}  // namespace

bool OutputsFollowContract(const std::vector<cv::Mat>& outputs, int level_h, int level_w) {
  if (outputs.size() != 3) return false;
  for (const cv::Mat& m : outputs)
    if (m.dims != 4 || m.size[0] != 1 || !m.isContinuous() || m.type() != CV_32F) return false;
  const int h = outputs[2].size[2], w = outputs[2].size[3];
  if (outputs[0].size[1] != 128 || outputs[1].size[1] != 1 || outputs[2].size[1] != 1)
    return false;
  for (const cv::Mat& m : outputs)
    if (m.size[2] != h || m.size[3] != w) return false;
  // faster2d2 (Fast_Quad_L2Net) max-pools by 2 (floor) and upsamples by 2: an
  // odd side loses its last pixel, in PyTorch as in OpenCV.
  return (h == level_h || h == level_h - 1) && (w == level_w || w == level_w - 1) && h > 0 &&
         w > 0;
}

bool R2d2Options::Check(std::string* why) const {
  if (model.empty()) {
    *why = "parameter 'model': the R2D2 .onnx file is required";
    return false;
  }
  if (!kapture::IsFeatureTypeName(type)) {
    *why = "parameter 'type': '" + type + "' is not a folder name";
    return false;
  }
  if (min_scale > max_scale) {
    *why = "parameter 'min_scale' is above 'max_scale'";
    return false;
  }
  if (min_size > max_size) {
    *why = "parameter 'min_size' is above 'max_size'";
    return false;
  }
  return true;
}

R2d2Features ExtractR2d2(const cv::Mat& rgb, const R2d2Options& o) {
  if (rgb.empty() || rgb.type() != CV_8UC3) throw Error("ExtractR2d2: expected an 8-bit RGB image");
  cv::dnn::Net& net = ThreadNet(o.model);
  const int H = rgb.rows, W = rgb.cols;
  const double longer = std::max(H, W);
  const double lowest = std::max(o.min_scale, o.min_size / longer);
  const double highest = std::min(o.max_scale, o.max_size / longer);
  static const std::vector<cv::String> kOutputs = {"descriptors", "reliability", "repeatability"};

  R2d2Features f;
  std::vector<Candidate> candidates;
  std::vector<float> candidate_descriptors;  // 128 per candidate
  cv::Mat image = Normalise(rgb);        // once; the pyramid resizes normalised images
  double s = 1.0;
  while (s + kScaleSlack >= lowest) {
    if (s - kScaleSlack <= highest) {
      net.setInput(ToBlob(image), "image");
      std::vector<cv::Mat> outputs;
      const auto start = std::chrono::steady_clock::now();
      net.forward(outputs, kOutputs);
      f.network_seconds +=
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (!OutputsFollowContract(outputs, image.rows, image.cols))
        throw InputError(o.model, 0, "model",
                         "outputs do not follow the R2D2 contract (descriptors 1x128xhxw, "
                         "reliability and repeatability 1x1xhxw, h x w = the input's " +
                             std::to_string(image.rows) + "x" + std::to_string(image.cols) +
                             " or one pixel less on an odd side)");
      DetectAtLevel(outputs[0], outputs[1], outputs[2], s, image.cols, image.rows, W, H, o,
                    &candidates, &candidate_descriptors);
      ++f.scales;
    }
    s /= kScaleFactor;
    // Python's round() rounds halves to even, as nearbyint does by default.
    const int nh = static_cast<int>(std::nearbyint(H * s)), nw = static_cast<int>(std::nearbyint(W * s));
    if (nh < 1 || nw < 1) break;
    cv::Mat next;
    cv::resize(image, next, cv::Size(nw, nh), 0, 0, cv::INTER_LINEAR);
    image = next;
  }

  if (f.scales == 0)
    throw InputError(o.model, 0, "min_size/max_size",
                     "no pyramid level (scales 2^(-k/4)) of this " + std::to_string(W) + "x" +
                         std::to_string(H) + " image lies between min_size " +
                         std::to_string(o.min_size) + " and max_size " + std::to_string(o.max_size) +
                         " (and min_scale/max_scale): the network would never run");

  // Best score first; ties keep the pooling order (coarser levels after finer).
  std::vector<size_t> order(candidates.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return candidates[a].score > candidates[b].score;
  });
  if (o.top_k > 0 && order.size() > static_cast<size_t>(o.top_k)) order.resize(o.top_k);

  const size_t n = order.size();
  f.raw_keypoints.reserve(3 * n);
  f.keypoints.reserve(3 * n);
  f.scores.reserve(n);
  f.descriptors.resize(128 * n);
  for (size_t i = 0; i < n; ++i) {
    const Candidate& c = candidates[order[i]];
    const float* src = &candidate_descriptors[128 * order[i]];
    f.raw_keypoints.insert(f.raw_keypoints.end(), {c.x, c.y, c.scale});
    f.keypoints.insert(f.keypoints.end(), {c.sdk_x, c.sdk_y, c.scale});
    f.scores.push_back(c.score);
    std::copy(src, src + 128, &f.descriptors[128 * i]);
  }
  return f;
}

}  // namespace locforge::learned

#include "densevlad.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

#include "locforge/error.h"

namespace locforge::retrieval {

namespace {

// Nearest centre of each row (ties: lowest index).
std::vector<int> Assign(const RowMatrix& x, const RowMatrix& centres, std::vector<float>* d2 = nullptr) {
  const Eigen::VectorXf cn = centres.rowwise().squaredNorm();
  std::vector<int> out(x.rows());
  if (d2) d2->assign(x.rows(), 0);
  constexpr int64_t kBlock = 4096;
  Eigen::MatrixXf dots;
  for (int64_t s = 0; s < x.rows(); s += kBlock) {
    const int64_t n = std::min(kBlock, x.rows() - s);
    dots.noalias() = x.middleRows(s, n) * centres.transpose();
    for (int64_t i = 0; i < n; ++i) {
      int best = 0;
      float best_d = std::numeric_limits<float>::infinity();
      for (int64_t c = 0; c < centres.rows(); ++c) {
        const float d = cn[c] - 2 * dots(i, c);
        if (d < best_d) best_d = d, best = static_cast<int>(c);
      }
      out[s + i] = best;
      if (d2) (*d2)[s + i] = std::max(0.f, best_d + x.row(s + i).squaredNorm());
    }
  }
  return out;
}

double Uniform01(std::mt19937_64& rng) { return (rng() >> 11) * 0x1.0p-53; }

}  // namespace

namespace {

// The grid points of one bin size: ceil(2 bin) from the border, so a
// descriptor's 4x4 bins (2 bin each side of its centre) lie in the image.
std::vector<cv::Point> GridPoints(const cv::Size& size, double bin, int step) {
  std::vector<cv::Point> out;
  const int margin = static_cast<int>(std::ceil(2 * bin));
  for (int y = margin; y < size.height - margin; y += step)
    for (int x = margin; x < size.width - margin; x += step) out.emplace_back(x, y);
  return out;
}

// Gradient magnitude split into 8 orientation maps, each pixel's magnitude
// shared linearly between the two nearest of the 8 orientations.
std::array<cv::Mat, 8> OrientationMaps(const cv::Mat& image) {
  cv::Mat gx, gy, magnitude, angle;
  cv::Sobel(image, gx, CV_32F, 1, 0, 1, 0.5, 0, cv::BORDER_REPLICATE);  // central differences
  cv::Sobel(image, gy, CV_32F, 0, 1, 1, 0.5, 0, cv::BORDER_REPLICATE);
  cv::cartToPolar(gx, gy, magnitude, angle);  // angle in [0, 2 pi)
  std::array<cv::Mat, 8> maps;
  for (auto& m : maps) m = cv::Mat::zeros(image.size(), CV_32F);
  for (int y = 0; y < image.rows; ++y) {
    const float* mag = magnitude.ptr<float>(y);
    const float* ang = angle.ptr<float>(y);
    for (int x = 0; x < image.cols; ++x) {
      const float t = ang[x] * static_cast<float>(8 / (2 * M_PI));
      const int lower = static_cast<int>(std::floor(t));
      const float w = t - static_cast<float>(lower);
      maps[((lower % 8) + 8) % 8].ptr<float>(y)[x] += mag[x] * (1 - w);
      maps[(lower + 1) % 8].ptr<float>(y)[x] += mag[x] * w;
    }
  }
  return maps;
}

// Value of a map at a real position (bilinear; 0 outside).
float Sample(const cv::Mat& map, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const float ax = static_cast<float>(x - x0), ay = static_cast<float>(y - y0);
  auto at = [&](int xx, int yy) {
    return xx < 0 || yy < 0 || xx >= map.cols || yy >= map.rows ? 0.f : map.ptr<float>(yy)[xx];
  };
  return (1 - ay) * ((1 - ax) * at(x0, y0) + ax * at(x0 + 1, y0)) +
         ay * ((1 - ax) * at(x0, y0 + 1) + ax * at(x0 + 1, y0 + 1));
}

// SIFT's normalisation (L2, clip at 0.2, L2) then RootSIFT (L1, square root).
void NormaliseRootSift(float* d) {
  auto l2 = [&] {
    double n = 0;
    for (int j = 0; j < 128; ++j) n += static_cast<double>(d[j]) * d[j];
    const float inv = n > 0 ? static_cast<float>(1 / std::sqrt(n)) : 0.f;
    for (int j = 0; j < 128; ++j) d[j] *= inv;
  };
  l2();
  for (int j = 0; j < 128; ++j) d[j] = std::min(d[j], 0.2f);
  l2();
  double l1 = 0;
  for (int j = 0; j < 128; ++j) l1 += d[j];
  const double inv = l1 > 0 ? 1.0 / l1 : 0.0;
  for (int j = 0; j < 128; ++j) d[j] = static_cast<float>(std::sqrt(d[j] * inv));
}

}  // namespace

// Dense SIFT as VLFeat's vl_dsift in its fast (flat-window) mode, the extractor
// of Torii et al.'s DenseVLAD (through vl_phow). Per bin size: the image is
// smoothed with sigma = sqrt((bin / 6)^2 - 0.25) (vl_phow's magnif 6, minus the
// image's own 0.5 blur), its gradient split into 8 orientation maps, each map
// convolved once with a triangular kernel of half-width `bin` (the bilinear
// weighting of a pixel into its neighbouring spatial bins), and each grid
// point's 4x4x8 values read at the 16 bin centres, (j - 1.5) bin from it.
// Cost per scale: O(pixels x 8 x bin), not O(points x window) as OpenCV's
// per-keypoint SIFT::compute (which global/densevlad 1.0.0 used: 7x SIFT's time).
RowMatrix DenseRootSift(const cv::Mat& gray_in, const DenseSiftOptions& o) {
  cv::Mat gray = gray_in;
  const int longer = std::max(gray_in.cols, gray_in.rows);
  if (o.max_image_size > 0 && longer > o.max_image_size) {
    const double s = static_cast<double>(o.max_image_size) / longer;
    cv::resize(gray_in, gray, cv::Size(), s, s, cv::INTER_AREA);
  }
  cv::Mat image;
  gray.convertTo(image, CV_32F, 1.0 / 255);
  std::vector<std::vector<cv::Point>> grids;
  int64_t total = 0;
  for (double bin : o.bin_sizes) {
    grids.push_back(GridPoints(image.size(), bin, o.grid_step));
    total += static_cast<int64_t>(grids.back().size());
  }
  RowMatrix out(total, 128);
  int64_t row = 0;
  for (size_t s = 0; s < o.bin_sizes.size(); ++s) {
    if (grids[s].empty()) continue;
    const double bin = o.bin_sizes[s];
    const double sigma = std::sqrt(std::max(0.0, bin * bin / 36 - 0.25));
    cv::Mat smooth = image;
    if (sigma > 0.01) cv::GaussianBlur(image, smooth, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
    const int half = static_cast<int>(std::ceil(bin)) - 1;  // taps with a non-zero weight
    cv::Mat kernel(2 * half + 1, 1, CV_32F);
    for (int d = -half; d <= half; ++d) kernel.at<float>(d + half) = static_cast<float>(1 - std::abs(d) / bin);
    std::array<cv::Mat, 8> maps = OrientationMaps(smooth);
    for (auto& m : maps) {
      cv::Mat spread;
      cv::sepFilter2D(m, spread, CV_32F, kernel, kernel, cv::Point(-1, -1), 0, cv::BORDER_CONSTANT);
      m = spread;
    }
    for (const cv::Point& p : grids[s]) {
      float* d = out.row(row++).data();
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
          for (int k = 0; k < 8; ++k)
            d[(i * 4 + j) * 8 + k] = Sample(maps[k], p.x + (j - 1.5) * bin, p.y + (i - 1.5) * bin);
      NormaliseRootSift(d);
    }
  }
  return out;
}

RowMatrix KMeans(const RowMatrix& x, int k, int iterations, uint64_t seed) {
  if (x.rows() < k) throw Error("k-means: " + std::to_string(x.rows()) + " samples for " + std::to_string(k) + " clusters");
  std::mt19937_64 rng(seed);
  RowMatrix c(k, x.cols());
  // k-means++ seeding.
  c.row(0) = x.row(static_cast<int64_t>(Uniform01(rng) * x.rows()));
  std::vector<float> d2(x.rows(), std::numeric_limits<float>::infinity());
  for (int j = 1; j < k; ++j) {
    double total = 0;
    for (int64_t i = 0; i < x.rows(); ++i) {
      d2[i] = std::min(d2[i], (x.row(i) - c.row(j - 1)).squaredNorm());
      total += d2[i];
    }
    double pick = Uniform01(rng) * total;
    int64_t chosen = x.rows() - 1;
    for (int64_t i = 0; i < x.rows(); ++i)
      if ((pick -= d2[i]) <= 0) {
        chosen = i;
        break;
      }
    c.row(j) = x.row(chosen);
  }
  for (int it = 0; it < iterations; ++it) {
    std::vector<float> dist;
    const auto assign = Assign(x, c, &dist);
    RowMatrix sum = RowMatrix::Zero(k, x.cols());
    std::vector<int64_t> count(k, 0);
    for (int64_t i = 0; i < x.rows(); ++i) sum.row(assign[i]) += x.row(i), ++count[assign[i]];
    for (int j = 0; j < k; ++j) {
      if (count[j] > 0) {
        c.row(j) = sum.row(j) / static_cast<float>(count[j]);
      } else {  // empty: restart on the worst-fitted sample
        const int64_t far = std::max_element(dist.begin(), dist.end()) - dist.begin();
        c.row(j) = x.row(far);
        dist[far] = 0;
      }
    }
  }
  return c;
}

Eigen::VectorXf Vlad(const RowMatrix& x, const RowMatrix& centres) {
  const int64_t k = centres.rows(), d = centres.cols();
  RowMatrix v = RowMatrix::Zero(k, d);
  const auto assign = Assign(x, centres);
  for (int64_t i = 0; i < x.rows(); ++i) v.row(assign[i]) += x.row(i) - centres.row(assign[i]);
  for (int64_t j = 0; j < k; ++j) {  // intra-normalisation
    const float n = v.row(j).norm();
    if (n > 0) v.row(j) /= n;
  }
  Eigen::VectorXf out = Eigen::Map<Eigen::VectorXf>(v.data(), k * d);
  out = out.array().sign() * out.array().abs().sqrt();  // power normalisation
  const float n = out.norm();
  if (n > 0) out /= n;
  return out;
}

void LearnPcaWhitening(const RowMatrix& vlads, int dims, Vocabulary* v) {
  const int64_t n = vlads.rows();
  if (n < 2) throw Error("PCA-whitening needs at least 2 map images");
  v->pca_mean = vlads.colwise().mean().transpose();
  const Eigen::MatrixXd centred = (vlads.rowwise() - v->pca_mean.transpose()).cast<double>();
  const Eigen::MatrixXd gram = centred * centred.transpose();  // n x n: D is large
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(gram);
  const Eigen::VectorXd values = eig.eigenvalues();  // ascending
  const double largest = values[n - 1];
  int kept = 0;
  while (kept < dims && kept < n - 1 && values[n - 1 - kept] > 1e-9 * largest) ++kept;
  v->pca_projection.resize(kept, vlads.cols());
  for (int i = 0; i < kept; ++i) {
    const double lambda = values[n - 1 - i];
    // Direction X^T u / sqrt(lambda), divided again by sqrt(lambda) to whiten.
    const Eigen::VectorXd dir = centred.transpose() * eig.eigenvectors().col(n - 1 - i) / lambda;
    v->pca_projection.row(i) = dir.cast<float>().transpose();
  }
}

Eigen::VectorXf DenseVladDescriptor(const cv::Mat& gray, const Vocabulary& v) {
  Eigen::VectorXf vlad = Vlad(DenseRootSift(gray, v.dense), v.centres);
  if (v.pca_projection.rows() == 0) return vlad;
  Eigen::VectorXf y = v.pca_projection * (vlad - v.pca_mean);
  const float n = y.norm();
  if (n > 0) y /= n;
  return y;
}

// ------------------------------------------------------------ file format
// "locforge-densevlad 2\n" + one text line of settings + raw little-endian
// float32 arrays: centres (K x 128), PCA mean (D) and projection (dims x D).

namespace {
constexpr const char* kMagic = "locforge-densevlad 2";  // 2: vl_dsift-style dense SIFT

void Append(std::string* out, const float* data, size_t count) {
  out->append(reinterpret_cast<const char*>(data), count * sizeof(float));
}
}  // namespace

std::string Vocabulary::Serialize() const {
  std::ostringstream head;
  head << kMagic << "\nclusters " << centres.rows() << " dim " << centres.cols() << " pca_dims "
       << pca_projection.rows() << " max_image_size " << dense.max_image_size << " grid_step "
       << dense.grid_step << " bin_sizes " << dense.bin_sizes.size();
  for (double b : dense.bin_sizes) head << " " << b;
  head << "\n";
  std::string out = head.str();
  Append(&out, centres.data(), centres.size());
  if (pca_projection.rows() > 0) {
    Append(&out, pca_mean.data(), pca_mean.size());
    Append(&out, pca_projection.data(), pca_projection.size());
  }
  return out;
}

Vocabulary Vocabulary::Parse(const std::string& bytes, const std::string& file) {
  const size_t l1 = bytes.find('\n');
  const size_t l2 = l1 == std::string::npos ? l1 : bytes.find('\n', l1 + 1);
  if (bytes.compare(0, 21, "locforge-densevlad 1\n") == 0)
    throw InputError(file, 1, "", "a version-1 vocabulary (OpenCV's per-keypoint dense SIFT, global/densevlad 1.0.0): "
                                  "its words do not fit global/densevlad 2.0.0's descriptors; train it again with "
                                  "global/densevlad_vocabulary 2.0.0");
  if (l2 == std::string::npos || bytes.compare(0, l1, kMagic) != 0)
    throw InputError(file, 1, "", "not a locforge DenseVLAD vocabulary");
  std::istringstream head(bytes.substr(l1 + 1, l2 - l1 - 1));
  std::string w[7];
  int64_t clusters = 0, dim = 0, pca = 0;
  size_t bins = 0;
  Vocabulary v;
  head >> w[0] >> clusters >> w[1] >> dim >> w[2] >> pca >> w[3] >> v.dense.max_image_size >> w[4] >>
      v.dense.grid_step >> w[5] >> bins;
  v.dense.bin_sizes.resize(bins < 16 ? bins : 0);
  for (double& b : v.dense.bin_sizes) head >> b;
  if (!head || w[0] != "clusters" || dim != 128 || clusters <= 0 || pca < 0 || bins == 0 || bins >= 16 ||
      v.dense.grid_step <= 0)
    throw InputError(file, 2, "", "malformed settings line");
  const int64_t full = clusters * dim;
  const size_t expected = sizeof(float) * (full + (pca > 0 ? full + pca * full : 0));
  if (bytes.size() - l2 - 1 != expected)
    throw InputError(file, 0, "", "size " + std::to_string(bytes.size() - l2 - 1) +
                                      " bytes of arrays, expected " + std::to_string(expected));
  const char* p = bytes.data() + l2 + 1;
  v.centres.resize(clusters, dim);
  std::memcpy(v.centres.data(), p, full * sizeof(float));
  p += full * sizeof(float);
  if (pca > 0) {
    v.pca_mean.resize(full);
    std::memcpy(v.pca_mean.data(), p, full * sizeof(float));
    p += full * sizeof(float);
    v.pca_projection.resize(pca, full);
    std::memcpy(v.pca_projection.data(), p, pca * full * sizeof(float));
  }
  return v;
}

}  // namespace locforge::retrieval

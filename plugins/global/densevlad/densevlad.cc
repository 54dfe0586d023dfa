#include "densevlad.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
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

RowMatrix DenseRootSift(const cv::Mat& gray_in, const DenseSiftOptions& o) {
  cv::Mat gray = gray_in;
  const int longer = std::max(gray_in.cols, gray_in.rows);
  if (o.max_image_size > 0 && longer > o.max_image_size) {
    const double s = static_cast<double>(o.max_image_size) / longer;
    cv::resize(gray_in, gray, cv::Size(), s, s, cv::INTER_AREA);
  }
  std::vector<cv::KeyPoint> grid;
  for (double bin : o.bin_sizes) {
    // OpenCV's SIFT bin width is 3 sigma = 1.5 x size; the 4x4 bins must fit.
    const float size = static_cast<float>(bin * 2.0 / 3.0);
    const int margin = static_cast<int>(std::ceil(2 * bin));
    for (int y = margin; y < gray.rows - margin; y += o.grid_step)
      for (int x = margin; x < gray.cols - margin; x += o.grid_step)
        grid.emplace_back(static_cast<float>(x), static_cast<float>(y), size, 0.f);
  }
  RowMatrix out(0, 128);
  if (grid.empty()) return out;
  cv::Mat descriptors;
  cv::SIFT::create()->compute(gray, grid, descriptors);
  out.resize(descriptors.rows, 128);
  for (int i = 0; i < descriptors.rows; ++i) {
    const float* d = descriptors.ptr<float>(i);
    double l1 = 0;
    for (int j = 0; j < 128; ++j) l1 += std::abs(d[j]);
    const double inv = l1 > 0 ? 1.0 / l1 : 0.0;
    for (int j = 0; j < 128; ++j) out(i, j) = static_cast<float>(std::sqrt(std::abs(d[j]) * inv));
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
// "locforge-densevlad 1\n" + one text line of settings + raw little-endian
// float32 arrays: centres (K x 128), PCA mean (D) and projection (dims x D).

namespace {
constexpr const char* kMagic = "locforge-densevlad 1";

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

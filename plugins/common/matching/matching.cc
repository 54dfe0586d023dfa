#include "matching.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "locforge/error.h"
#include "nearest_avx2.h"
#include "nearest_vnni.h"

namespace locforge::matching {

DescriptorMatrix NormalisedDescriptors(const kapture::FeatureArray& d) {
  DescriptorMatrix m(d.rows, d.dsize);
  for (int64_t r = 0; r < d.rows; ++r)
    for (int64_t c = 0; c < d.dsize; ++c) m(r, c) = static_cast<float>(d.At(r, c));
  for (int64_t r = 0; r < d.rows; ++r) {
    const float n = m.row(r).norm();
    if (n > 0) m.row(r) /= n;
  }
  return m;
}

std::optional<ByteDescriptors> ByteDescriptorsOf(const kapture::FeatureArray& d) {
  if (d.dtype != kapture::DType::kUint8) return std::nullopt;
  ByteDescriptors out;
  out.rows = d.rows;
  out.dims = d.dsize;
  const uint8_t* values = d.data<uint8_t>();
  out.values.assign(values, values + d.rows * d.dsize);
  out.inv_norm.resize(d.rows, 0.f);
  for (int64_t r = 0; r < d.rows; ++r) {
    int64_t squares = 0;
    for (int64_t c = 0; c < d.dsize; ++c) squares += int64_t{values[r * d.dsize + c]} * values[r * d.dsize + c];
    if (squares > 0) out.inv_norm[r] = static_cast<float>(1.0 / std::sqrt(static_cast<double>(squares)));
  }
  return out;
}

namespace {

Eigen::Matrix3d Skew(const Eigen::Vector3d& t) {
  Eigen::Matrix3d s;
  s << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  return s;
}

// The relative pose x2 = R x1 + t of two world-to-camera poses and its
// essential matrix [t / |t|]x R (none when the centres coincide).
struct PosePairGeometry {
  Eigen::Matrix3d R;
  std::optional<Eigen::Matrix3d> E;
};

PosePairGeometry GeometryOfPoses(const Pose& T1_world, const Pose& T2_world) {
  const Pose T21 = T2_world * T1_world.Inverse();
  PosePairGeometry g{T21.R(), std::nullopt};
  if (T21.t.norm() >= 1e-6) g.E = Skew(T21.t.normalized()) * g.R;
  return g;
}

// Pixels per unit of the normalised image plane, for both images at once.
double MeanFocal(const Camera& c1, const Camera& c2) { return 0.25 * (c1.fx() + c1.fy() + c2.fx() + c2.fy()); }

}  // namespace

std::optional<EpipolarBand> EpipolarBand::Make(const std::vector<Eigen::Vector2d>& pa,
                                                const std::vector<Eigen::Vector2d>& pb, const Camera& ca,
                                                const Camera& cb, const Pose& Ta, const Pose& Tb,
                                                double max_error_px) {
  const PosePairGeometry g = GeometryOfPoses(Ta, Tb);
  if (!g.E) return std::nullopt;
  const Eigen::Matrix3d& E = *g.E;
  const double focal = MeanFocal(ca, cb);
  EpipolarBand band;
  band.t2_ = static_cast<float>(max_error_px * max_error_px / (focal * focal));
  for (const auto& p : pa) {
    const Eigen::Vector3d l = E * ca.Unproject(p);
    band.lx_.push_back(static_cast<float>(l.x()));
    band.ly_.push_back(static_cast<float>(l.y()));
    band.lz_.push_back(static_cast<float>(l.z()));
    band.row_den_.push_back(static_cast<float>(l.head<2>().squaredNorm()));
  }
  band.cols_ = static_cast<int64_t>(pb.size());
  const size_t padded = static_cast<size_t>(simd::PanelPadded(band.cols_));  // the SIMD scans read whole panels
  for (auto* v : {&band.cx_, &band.cy_, &band.cz_, &band.col_den_}) v->reserve(padded);
  for (const auto& p : pb) {
    const Eigen::Vector3d x = cb.Unproject(p), m = E.transpose() * x;
    band.cx_.push_back(static_cast<float>(x.x()));
    band.cy_.push_back(static_cast<float>(x.y()));
    band.cz_.push_back(static_cast<float>(x.z()));
    band.col_den_.push_back(static_cast<float>(m.head<2>().squaredNorm()));
  }
  for (auto* v : {&band.cx_, &band.cy_, &band.cz_, &band.col_den_}) v->resize(padded, 0.f);
  return band;
}

namespace {

// The portable scan: Eigen products of 1024-row blocks of a against b.
void ScanNearestEigen(const DescriptorMatrix& a, const DescriptorMatrix& b, const simd::BandArrays* band, int* best,
                      float* best_sim, float* second_sim, int* col_best, float* col_best_sim) {
  const int64_t n = a.rows(), m = b.rows();
  constexpr int64_t kBlock = 1024;
  Eigen::MatrixXf sim;
  for (int64_t start = 0; start < n; start += kBlock) {
    const int64_t rows = std::min(kBlock, n - start);
    sim.noalias() = a.middleRows(start, rows) * b.transpose();
    for (int64_t r = 0; r < rows; ++r) {
      const int64_t i = start + r;
      for (int64_t j = 0; j < m; ++j) {
        if (band && !simd::InBand(*band, i, j)) continue;
        avx2::UpdateRow(i, j, sim(r, j), best, best_sim, second_sim);
        avx2::UpdateColumn(i, j, sim(r, j), col_best, col_best_sim);
      }
    }
  }
}

// Byte rows as float values, unnormalised (their dot products exact up to
// vnni::kMaxExactFloatDims dimensions).
DescriptorMatrix ByteValues(const ByteDescriptors& d) {
  return Eigen::Map<const Eigen::Matrix<uint8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
             d.values.data(), d.rows, d.dims).cast<float>();
}

// The portable byte scan: exact products of 1024-row blocks of a against b
// (Eigen, in float up to vnni::kMaxExactFloatDims dimensions, else int32),
// each made a similarity by vnni::ByteSimilarity.
template <class Scalar>
void ScanNearestBytes(const ByteDescriptors& a, const ByteDescriptors& b, const simd::BandArrays* band, int* best,
                      float* best_sim, float* second_sim, int* col_best, float* col_best_sim) {
  using Rows = Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  using ByteRows = Eigen::Matrix<uint8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const int64_t n = a.rows, m = b.rows, dims = a.dims;
  const Rows bs = Eigen::Map<const ByteRows>(b.values.data(), m, dims).template cast<Scalar>();
  constexpr int64_t kBlock = 1024;
  Rows dot;
  for (int64_t start = 0; start < n; start += kBlock) {
    const int64_t rows = std::min(kBlock, n - start);
    const Rows as = Eigen::Map<const ByteRows>(a.values.data() + start * dims, rows, dims).template cast<Scalar>();
    dot.noalias() = as * bs.transpose();
    for (int64_t r = 0; r < rows; ++r) {
      const int64_t i = start + r;
      for (int64_t j = 0; j < m; ++j) {
        if (band && !simd::InBand(*band, i, j)) continue;
        const float s = vnni::ByteSimilarity(static_cast<int32_t>(dot(r, j)), a.inv_norm[i], b.inv_norm[j]);
        avx2::UpdateRow(i, j, s, best, best_sim, second_sim);
        avx2::UpdateColumn(i, j, s, col_best, col_best_sim);
      }
    }
  }
}

// The running results of a scan over n rows and m columns.
struct Nearest {
  static constexpr float kNone = -std::numeric_limits<float>::infinity();
  Nearest(int64_t n, int64_t m)
      : best(n, -1), best_sim(n, kNone), second_sim(n, kNone), col_best(m, -1), col_best_sim(m, kNone) {}
  std::vector<int> best;
  std::vector<float> best_sim, second_sim;
  std::vector<int> col_best;
  std::vector<float> col_best_sim;
};

// The mutual check, distance and ratio tests on a finished scan.
std::vector<kapture::Match> SelectMatches(const Nearest& s, const NnOptions& o) {
  std::vector<kapture::Match> out;
  const int64_t n = static_cast<int64_t>(s.best.size()), m = static_cast<int64_t>(s.col_best.size());
  auto distance = [](float sim) { return std::sqrt(std::max(0.0, 2.0 - 2.0 * sim)); };
  for (int64_t i = 0; i < n; ++i) {
    const int j = s.best[i];
    if (j < 0) continue;
    if (o.cross_check && s.col_best[j] != i) continue;
    const double d1 = distance(s.best_sim[i]);
    if (d1 > o.max_distance) continue;
    if (o.ratio < 1.0 && m > 1 && !(d1 < o.ratio * distance(s.second_sim[i]))) continue;
    out.push_back({static_cast<double>(i), static_cast<double>(j), s.best_sim[i]});
  }
  return out;
}

void CheckSameSize(int64_t dims_a, int64_t dims_b) {
  if (dims_a != dims_b)
    throw InputError("descriptor sizes differ: " + std::to_string(dims_a) + " vs " + std::to_string(dims_b));
}

// The band's view, checked against the scan's size (null without a band).
std::optional<simd::BandArrays> BandView(const EpipolarBand* band, int64_t n, int64_t m) {
  if (!band) return std::nullopt;
  if (band->rows() != n || band->cols() != m)
    throw Error("epipolar band of " + std::to_string(band->rows()) + " x " + std::to_string(band->cols()) +
                " keypoints for " + std::to_string(n) + " x " + std::to_string(m) + " descriptors");
  return band->View();
}

}  // namespace

std::vector<kapture::Match> MatchDescriptors(const DescriptorMatrix& a, const DescriptorMatrix& b,
                                             const NnOptions& o, const EpipolarBand* epipolar_band) {
  const int64_t n = a.rows(), m = b.rows();
  if (n == 0 || m == 0) return {};
  CheckSameSize(a.cols(), b.cols());
  const std::optional<simd::BandArrays> view = BandView(epipolar_band, n, m);
  const simd::BandArrays* band = view ? &*view : nullptr;
  Nearest s(n, m);
  static const bool kAvx2 = avx2::Supported();
  if (o.use_simd && kAvx2 && a.cols() % 8 == 0)
    avx2::ScanNearest(a.data(), n, b.data(), m, a.cols(), band, s.best.data(), s.best_sim.data(),
                      s.second_sim.data(), s.col_best.data(), s.col_best_sim.data());
  else
    ScanNearestEigen(a, b, band, s.best.data(), s.best_sim.data(), s.second_sim.data(), s.col_best.data(),
                     s.col_best_sim.data());
  return SelectMatches(s, o);
}

std::vector<kapture::Match> MatchDescriptors(const ByteDescriptors& a, const ByteDescriptors& b,
                                             const NnOptions& o, const EpipolarBand* epipolar_band) {
  const int64_t n = a.rows, m = b.rows;
  if (n == 0 || m == 0) return {};
  CheckSameSize(a.dims, b.dims);
  const std::optional<simd::BandArrays> view = BandView(epipolar_band, n, m);
  const simd::BandArrays* band = view ? &*view : nullptr;
  if (a.dims > vnni::kMaxDims)
    throw InputError("byte descriptors of " + std::to_string(a.dims) + " dimensions: at most " +
                     std::to_string(vnni::kMaxDims) + " are matched exactly");
  Nearest s(n, m);
  static const bool kVnni = vnni::Supported(), kAvx2 = avx2::Supported();
  const bool exact_in_float = a.dims <= vnni::kMaxExactFloatDims;
  int *best = s.best.data(), *col_best = s.col_best.data();
  float *best_sim = s.best_sim.data(), *second_sim = s.second_sim.data(), *col_best_sim = s.col_best_sim.data();
  if (o.use_simd && kVnni && a.dims % 4 == 0) {
    vnni::ScanNearest(a.values.data(), n, a.inv_norm.data(), b.values.data(), m, b.inv_norm.data(), a.dims, band,
                      best, best_sim, second_sim, col_best, col_best_sim);
  } else if (o.use_simd && kAvx2 && a.dims % 8 == 0 && exact_in_float) {
    const DescriptorMatrix fa = ByteValues(a), fb = ByteValues(b);
    avx2::ScanNearestScaled(fa.data(), n, a.inv_norm.data(), fb.data(), m, b.inv_norm.data(), a.dims, band,
                            best, best_sim, second_sim, col_best, col_best_sim);
  } else if (exact_in_float) {
    ScanNearestBytes<float>(a, b, band, best, best_sim, second_sim, col_best, col_best_sim);
  } else {
    ScanNearestBytes<int32_t>(a, b, band, best, best_sim, second_sim, col_best, col_best_sim);
  }
  return SelectMatches(s, o);
}

namespace {

int UsacMethod(const std::string& method) {
  if (method == "magsac") return cv::USAC_MAGSAC;
  if (method == "usac") return cv::USAC_DEFAULT;
  throw ParamError("parameter 'method': unknown '" + method + "'");
}

Eigen::Matrix3d ToEigen(const cv::Mat& m) {
  Eigen::Matrix3d e;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) e(r, c) = m.at<double>(r, c);
  return e;
}

}  // namespace

TwoViewResult VerifyTwoView(const std::vector<Eigen::Vector2d>& p1,
                            const std::vector<Eigen::Vector2d>& p2, const Camera* c1,
                            const Camera* c2, const TwoViewOptions& o) {
  if (p1.size() != p2.size()) throw Error("VerifyTwoView: point counts differ");
  TwoViewResult result;
  const bool essential = c1 && c2;
  const size_t min_points = essential ? 5 : 8;
  if (p1.size() < min_points) return result;
  std::vector<cv::Point2d> a, b;
  a.reserve(p1.size());
  b.reserve(p2.size());
  for (size_t i = 0; i < p1.size(); ++i) {
    if (essential) {
      const Eigen::Vector3d r1 = c1->Unproject(p1[i]), r2 = c2->Unproject(p2[i]);
      a.emplace_back(r1.x(), r1.y());
      b.emplace_back(r2.x(), r2.y());
    } else {
      a.emplace_back(p1[i].x(), p1[i].y());
      b.emplace_back(p2[i].x(), p2[i].y());
    }
  }
  cv::Mat mask, model;
  if (essential) {
    const double focal = MeanFocal(*c1, *c2);
    model = cv::findEssentialMat(a, b, cv::Mat::eye(3, 3, CV_64F), UsacMethod(o.method),
                                 o.confidence, o.max_error_px / focal, o.max_iterations, mask);
  } else {
    model = cv::findFundamentalMat(a, b, UsacMethod(o.method), o.max_error_px, o.confidence,
                                   o.max_iterations, mask);
  }
  if (model.rows != 3 || model.cols != 3 || mask.empty()) return result;  // degenerate
  result.model = essential ? "essential" : "fundamental";
  result.matrix = ToEigen(model);
  for (int i = 0; i < static_cast<int>(p1.size()); ++i)
    if (mask.at<uchar>(i)) result.inliers.push_back(i);
  return result;
}

std::vector<double> EpipolarErrorsPx(const std::vector<Eigen::Vector2d>& p1,
                                     const std::vector<Eigen::Vector2d>& p2, const Camera& c1,
                                     const Camera& c2, const Pose& T1_world, const Pose& T2_world) {
  const PosePairGeometry g = GeometryOfPoses(T1_world, T2_world);
  const double focal = MeanFocal(c1, c2);
  std::vector<double> errors(p1.size());
  for (size_t i = 0; i < p1.size(); ++i) {
    const Eigen::Vector3d x1 = c1.Unproject(p1[i]), x2 = c2.Unproject(p2[i]);
    if (!g.E) {  // no baseline: the transfer error by the rotation
      const Eigen::Vector3d r = g.R * x1;
      errors[i] = r.z() > 0 ? focal * (r.hnormalized() - x2.hnormalized()).norm()
                            : std::numeric_limits<double>::infinity();
      continue;
    }
    const Eigen::Vector3d Ex1 = *g.E * x1, Etx2 = g.E->transpose() * x2;
    const double num = x2.dot(Ex1);
    const double den = Ex1.head<2>().squaredNorm() + Etx2.head<2>().squaredNorm();
    errors[i] = den > 0 ? focal * std::abs(num) / std::sqrt(den) : std::numeric_limits<double>::infinity();
  }
  return errors;
}

}  // namespace locforge::matching

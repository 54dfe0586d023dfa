// Descriptor matching and two-view verification, free of any I/O.
//
// Descriptors are compared by cosine similarity, so distances of unit
// vectors are in [0, 2] whatever the stored dtype: float rows L2-normalised
// (DescriptorMatrix), byte rows (SIFT's uint8) by their exact integer dot
// products and inverse norms (ByteDescriptors), the same bits on any processor.
#ifndef LOCFORGE_PLUGINS_COMMON_MATCHING_MATCHING_H_
#define LOCFORGE_PLUGINS_COMMON_MATCHING_MATCHING_H_

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "locforge/camera.h"
#include "locforge/kapture/features.h"
#include "locforge/pose.h"
#include "nearest_band.h"

namespace locforge::matching {

using DescriptorMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Any numeric descriptor array as rows of unit L2 norm (zero rows stay zero).
DescriptorMatrix NormalisedDescriptors(const kapture::FeatureArray& descriptors);

// Byte rows as stored (no conversion), with 1 / L2 norm of each (0 for a zero row).
struct ByteDescriptors {
  int64_t rows = 0, dims = 0;
  std::vector<uint8_t> values;  // rows x dims, row-major
  std::vector<float> inv_norm;
};

// uint8 descriptor arrays as ByteDescriptors; nullopt for any other dtype.
std::optional<ByteDescriptors> ByteDescriptorsOf(const kapture::FeatureArray& descriptors);

// Candidates restricted by two known poses: row i (keypoint x_a of image a)
// and column j (x_b of image b) may match only when the Sampson distance of
// the pair to the poses' epipolar geometry, in pixels by the mean focal
// length (as EpipolarErrorsPx), is at most max_error_px. The nearest, the
// second nearest of the ratio test and the mutual check are then all taken
// among those candidates: a feature repeated elsewhere in the image no longer
// fails the ratio test, one repeated along its epipolar line still does.
class EpipolarBand {
 public:
  // nullopt when the poses share their centre (no epipolar geometry).
  static std::optional<EpipolarBand> Make(const std::vector<Eigen::Vector2d>& pixels_a,
                                          const std::vector<Eigen::Vector2d>& pixels_b, const Camera& camera_a,
                                          const Camera& camera_b, const Pose& T_a_world, const Pose& T_b_world,
                                          double max_error_px);
  int64_t rows() const { return static_cast<int64_t>(lx_.size()); }
  int64_t cols() const { return cols_; }
  // The scans' view (nearest_band.h); column arrays padded to whole panels.
  simd::BandArrays View() const {
    return {lx_.data(), ly_.data(), lz_.data(), row_den_.data(), cx_.data(), cy_.data(), cz_.data(),
            col_den_.data(), t2_};
  }

 private:
  std::vector<float> lx_, ly_, lz_, row_den_, cx_, cy_, cz_, col_den_;
  int64_t cols_ = 0;
  float t2_ = 0;
};

struct NnOptions {
  bool cross_check = true;   // keep i<->j only when each is the other's nearest
  double ratio = 1.0;        // Lowe's ratio d1/d2 must be below this (1: off)
  double max_distance = 2.0; // L2 distance of unit descriptors must be <= this (2: off)
  bool use_simd = true;      // the AVX2 (float) / VNNI (bytes) scan where the processor has it (false: the portable scan)
};

// Nearest neighbours of the rows of `a` among the rows of `b`; score = cosine
// similarity. Sorted by index in `a`. Memory O(1024 x rows(b)).
std::vector<kapture::Match> MatchDescriptors(const DescriptorMatrix& a, const DescriptorMatrix& b,
                                             const NnOptions& options, const EpipolarBand* band = nullptr);
// The same for byte rows: similarities from exact integer dot products
// (nearest_vnni.h), so the SIMD and portable scans agree to the bit.
std::vector<kapture::Match> MatchDescriptors(const ByteDescriptors& a, const ByteDescriptors& b,
                                             const NnOptions& options, const EpipolarBand* band = nullptr);

// ------------------------------------------------------------ verification

struct TwoViewOptions {
  double max_error_px = 4.0;   // RANSAC inlier threshold in pixels
  double confidence = 0.9999;
  int max_iterations = 10000;
  std::string method = "magsac";  // "magsac" (cv::USAC_MAGSAC) or "usac" (cv::USAC_DEFAULT)
};

struct TwoViewResult {
  std::string model;             // "essential", "fundamental" or "" (too few matches)
  std::vector<int> inliers;      // indices into the given correspondences
  Eigen::Matrix3d matrix = Eigen::Matrix3d::Zero();  // E (normalised coordinates) or F (pixels)
};

// Pixels of image 1 / 2 (one row per correspondence). With both cameras,
// an essential matrix on undistorted normalised coordinates (threshold
// max_error_px / mean focal); without, a fundamental matrix in pixels.
TwoViewResult VerifyTwoView(const std::vector<Eigen::Vector2d>& pixels1,
                            const std::vector<Eigen::Vector2d>& pixels2, const Camera* camera1,
                            const Camera* camera2, const TwoViewOptions& options);

// Sampson distance (pixels, by the mean focal length) of each correspondence
// to the epipolar geometry of two known world-to-camera poses. When the
// centres coincide (no baseline) it is the transfer error by the rotation.
std::vector<double> EpipolarErrorsPx(const std::vector<Eigen::Vector2d>& pixels1,
                                     const std::vector<Eigen::Vector2d>& pixels2,
                                     const Camera& camera1, const Camera& camera2,
                                     const Pose& T1_world, const Pose& T2_world);

}  // namespace locforge::matching

#endif  // LOCFORGE_PLUGINS_COMMON_MATCHING_MATCHING_H_

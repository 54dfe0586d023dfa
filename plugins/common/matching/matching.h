// Descriptor matching and two-view verification, free of any I/O.
//
// Descriptors are compared as L2-normalised float vectors (uint8 SIFT rows
// are converted and normalised first), so distances are in [0, 2] whatever
// the stored dtype, and a match's score is the cosine similarity.
#ifndef LOCFORGE_PLUGINS_COMMON_MATCHING_MATCHING_H_
#define LOCFORGE_PLUGINS_COMMON_MATCHING_MATCHING_H_

#include <Eigen/Core>
#include <string>
#include <vector>

#include "locforge/camera.h"
#include "locforge/kapture/features.h"
#include "locforge/pose.h"

namespace locforge::matching {

using DescriptorMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Any numeric descriptor array as rows of unit L2 norm (zero rows stay zero).
DescriptorMatrix NormalisedDescriptors(const kapture::FeatureArray& descriptors);

struct NnOptions {
  bool cross_check = true;   // keep i<->j only when each is the other's nearest
  double ratio = 1.0;        // Lowe's ratio d1/d2 must be below this (1: off)
  double max_distance = 2.0; // L2 distance of unit descriptors must be <= this (2: off)
  bool use_avx2 = true;      // AVX2 + FMA scan where the processor has them (false: the portable Eigen scan)
};

// Nearest neighbours of the rows of `a` among the rows of `b`; score = cosine
// similarity. Sorted by index in `a`. Memory O(1024 x rows(b)).
std::vector<kapture::Match> MatchDescriptors(const DescriptorMatrix& a, const DescriptorMatrix& b,
                                             const NnOptions& options);

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

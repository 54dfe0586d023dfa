// DenseVLAD (Torii et al., CVPR 2015): dense multi-scale RootSIFT on a grid,
// VLAD on a k-means vocabulary learnt on the map images, intra-normalised,
// power-normalised (signed square root) and L2-normalised, optionally
// PCA-whitened (learnt on the map) and L2-normalised again.
#ifndef LOCFORGE_PLUGINS_GLOBAL_DENSEVLAD_DENSEVLAD_H_
#define LOCFORGE_PLUGINS_GLOBAL_DENSEVLAD_DENSEVLAD_H_

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "locforge/fs.h"

namespace cv {
class Mat;
}

namespace locforge::retrieval {

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct DenseSiftOptions {
  int max_image_size = 480;              // images downscaled so the longer side <= this
  int grid_step = 4;                     // pixels between grid points
  std::vector<double> bin_sizes = {4, 6, 8, 10};  // SIFT spatial bin widths (pixels)
};

// Dense RootSIFT descriptors (rows, 128 columns) of an 8-bit grey image.
RowMatrix DenseRootSift(const cv::Mat& gray, const DenseSiftOptions& options);

// k-means++ seeding then Lloyd iterations; deterministic for a seed.
RowMatrix KMeans(const RowMatrix& samples, int clusters, int iterations, uint64_t seed);

struct Vocabulary {
  DenseSiftOptions dense;
  RowMatrix centres;            // K x 128
  Eigen::VectorXf pca_mean;     // empty when no PCA
  RowMatrix pca_projection;     // dims x (K*128), rows already whitened

  int Dimension() const {
    return pca_projection.rows() > 0 ? static_cast<int>(pca_projection.rows())
                                     : static_cast<int>(centres.rows() * centres.cols());
  }
  std::string Serialize() const;
  // Throws InputError naming `file` on a malformed vocabulary.
  static Vocabulary Parse(const std::string& bytes, const std::string& file);
};

// VLAD of local descriptors (intra, power and L2 normalised), K*128 values.
Eigen::VectorXf Vlad(const RowMatrix& descriptors, const RowMatrix& centres);

// Learns PCA-whitening on VLAD rows: fills pca_mean and pca_projection with
// at most `dims` components (also at most rows - 1).
void LearnPcaWhitening(const RowMatrix& vlads, int dims, Vocabulary* vocabulary);

// The final descriptor: VLAD, then PCA-whitening + L2 when learnt.
Eigen::VectorXf DenseVladDescriptor(const cv::Mat& gray, const Vocabulary& vocabulary);

}  // namespace locforge::retrieval

#endif  // LOCFORGE_PLUGINS_GLOBAL_DENSEVLAD_DENSEVLAD_H_

// Sparse symmetric positive definite systems shaped like a bundle
// adjustment's reduced camera system, for TiledCholesky's test and benchmark.
#ifndef LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_REDUCED_SYSTEMS_H_
#define LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_REDUCED_SYSTEMS_H_

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

namespace locforge::sfm {

struct Sparse {
  int64_t n = 0;
  std::vector<int64_t> start, row;  // lower triangle by columns
  std::vector<double> value;
  Eigen::MatrixXd dense;  // the same matrix
};

// 6 x 6 blocks: `blocks` poses, each coupled to the next `band` (a
// trajectory) and `loops` random far pairs (loop closures); every coupled
// pair gets a residual of 8 rows with Gaussian Jacobians, plus 0.5 I.
inline Sparse MakeSystem(int blocks, int band, int loops, unsigned seed) {
  std::mt19937 random(seed);
  const int n = 6 * blocks;
  std::vector<std::pair<int, int>> pairs;
  for (int b = 0; b < blocks; ++b)
    for (int c = b + 1; c <= std::min(blocks - 1, b + band); ++c) pairs.emplace_back(b, c);
  std::uniform_int_distribution<int> any(0, blocks - 1);
  for (int l = 0; l < loops; ++l) {
    const int a = any(random), b = any(random);
    if (a != b) pairs.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::normal_distribution<double> normal;
  Sparse s;
  s.n = n;
  s.dense = Eigen::MatrixXd::Identity(n, n) * 0.5;
  for (const auto& [a, b] : pairs) {
    Eigen::Matrix<double, 8, 6> Ja, Jb;
    for (int i = 0; i < 8; ++i)
      for (int k = 0; k < 6; ++k) {
        Ja(i, k) = normal(random);
        Jb(i, k) = normal(random);
      }
    s.dense.block<6, 6>(6 * a, 6 * a) += Ja.transpose() * Ja;
    s.dense.block<6, 6>(6 * b, 6 * b) += Jb.transpose() * Jb;
    s.dense.block<6, 6>(6 * b, 6 * a) += Jb.transpose() * Ja;
    s.dense.block<6, 6>(6 * a, 6 * b) += Ja.transpose() * Jb;
  }
  s.start.push_back(0);
  for (int c = 0; c < n; ++c) {
    for (int r = c; r < n; ++r)
      if (s.dense(r, c) != 0) {
        s.row.push_back(r);
        s.value.push_back(s.dense(r, c));
      }
    s.start.push_back(static_cast<int64_t>(s.row.size()));
  }
  return s;
}

}  // namespace locforge::sfm

#endif  // LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_REDUCED_SYSTEMS_H_

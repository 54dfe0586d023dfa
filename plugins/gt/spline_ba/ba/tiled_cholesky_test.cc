#include "tiled_cholesky.h"

#include "reduced_systems.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <limits>
#include <numeric>
#include <random>
#include <vector>

namespace locforge::sfm {
namespace {

std::vector<int64_t> Shuffled(int64_t n, unsigned seed) {
  std::vector<int64_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(seed));
  return order;
}

TEST(TiledCholesky, SolvesLikeADenseFactorisationAtEveryTileSize) {
  const Sparse s = MakeSystem(40, 2, 15, 1);
  Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(s.n, -1, 2);
  const Eigen::VectorXd expected = s.dense.llt().solve(b);
  for (const auto& order : {Shuffled(s.n, 0), Shuffled(s.n, 7)})
    for (int tile : {1, 5, 6, 13, 64, 240, 500}) {
      TiledCholesky cholesky;
      ASSERT_EQ(cholesky.Analyze(s.n, s.start.data(), s.row.data(), order.data(), tile), "");
      ASSERT_TRUE(cholesky.Factorize(s.value.data(), 2));
      Eigen::VectorXd x(s.n);
      cholesky.Solve(b.data(), x.data());
      EXPECT_LT((x - expected).norm(), 1e-9 * expected.norm()) << "tile " << tile;
      EXPECT_LT((s.dense * x - b).norm(), 1e-9 * b.norm()) << "tile " << tile;
    }
}

TEST(TiledCholesky, SkipsTilesThatStayZero) {
  // A band matrix in its own order: the factor stays inside the band.
  const Sparse s = MakeSystem(60, 1, 0, 2);
  std::vector<int64_t> identity(s.n);
  std::iota(identity.begin(), identity.end(), 0);
  TiledCholesky cholesky;
  ASSERT_EQ(cholesky.Analyze(s.n, s.start.data(), s.row.data(), identity.data(), 12), "");
  // 30 tile columns: the diagonal and one tile below each (the band is 12 wide).
  EXPECT_EQ(cholesky.stored_values(), (30 + 29) * 12 * 12);
  EXPECT_EQ(cholesky.dense_values(), 30 * 31 / 2 * 12 * 12);
  ASSERT_TRUE(cholesky.Factorize(s.value.data(), 1));
  Eigen::VectorXd b = Eigen::VectorXd::Ones(s.n), x(s.n);
  cholesky.Solve(b.data(), x.data());
  EXPECT_LT((s.dense * x - b).norm(), 1e-9 * b.norm());
}

TEST(TiledCholesky, SameBitsAtAnyThreadCount) {
  const Sparse s = MakeSystem(80, 3, 40, 3);
  const std::vector<int64_t> order = Shuffled(s.n, 3);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(s.n, 1, 3);
  std::vector<Eigen::VectorXd> solutions;
  for (int threads : {1, 2, 3, 4}) {
    TiledCholesky cholesky;
    ASSERT_EQ(cholesky.Analyze(s.n, s.start.data(), s.row.data(), order.data(), 16), "");
    ASSERT_TRUE(cholesky.Factorize(s.value.data(), threads));
    solutions.emplace_back(s.n);
    cholesky.Solve(b.data(), solutions.back().data());
  }
  for (size_t k = 1; k < solutions.size(); ++k)
    for (int64_t i = 0; i < s.n; ++i) ASSERT_EQ(solutions[k][i], solutions[0][i]) << "threads run " << k << " entry " << i;
  EXPECT_LT((s.dense * solutions[0] - b).norm(), 1e-9 * b.norm());
}

TEST(TiledCholesky, RefusesAnIndefiniteOrNonFiniteMatrix) {
  Sparse s = MakeSystem(20, 2, 5, 4);
  const std::vector<int64_t> order = Shuffled(s.n, 4);
  TiledCholesky cholesky;
  ASSERT_EQ(cholesky.Analyze(s.n, s.start.data(), s.row.data(), order.data(), 8), "");
  ASSERT_TRUE(cholesky.Factorize(s.value.data(), 2));
  std::vector<double> indefinite = s.value;
  indefinite[s.start[57]] = -1e3;  // a negative diagonal entry
  EXPECT_FALSE(cholesky.Factorize(indefinite.data(), 2));
  std::vector<double> not_finite = s.value;
  not_finite[s.start[10] + 1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(cholesky.Factorize(not_finite.data(), 2));
  ASSERT_TRUE(cholesky.Factorize(s.value.data(), 2));  // usable again
}

TEST(TiledCholesky, RefusesABadOrderingOrPattern) {
  const Sparse s = MakeSystem(5, 1, 0, 5);
  std::vector<int64_t> order(s.n, 0);
  TiledCholesky cholesky;
  EXPECT_NE(cholesky.Analyze(s.n, s.start.data(), s.row.data(), order.data(), 4), "");
  std::iota(order.begin(), order.end(), 0);
  std::vector<int64_t> row = s.row;
  row[3] = s.n + 2;
  EXPECT_NE(cholesky.Analyze(s.n, s.start.data(), row.data(), order.data(), 4), "");
  EXPECT_NE(cholesky.Analyze(s.n, s.start.data(), s.row.data(), order.data(), 0), "");
}

}  // namespace
}  // namespace locforge::sfm

#include "tiled_cholesky.h"

#include "parallel_for.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <utility>

namespace locforge::sfm {

namespace {

using Map = Eigen::Map<Eigen::MatrixXd>;
using ConstMap = Eigen::Map<const Eigen::MatrixXd>;

}  // namespace

std::string TiledCholesky::Analyze(int64_t n, const int64_t* column_start, const int64_t* row, const int64_t* order,
                                   int tile) {
  if (n < 0 || tile < 1) return "need n >= 0 and tile >= 1";
  n_ = n;
  tile_ = tile;
  num_tiles_ = static_cast<int>((n + tile - 1) / tile);
  order_.assign(order, order + n);
  std::vector<int64_t> pivot(n, -1);  // original index -> pivot
  for (int64_t k = 0; k < n; ++k) {
    if (order_[k] < 0 || order_[k] >= n || pivot[order_[k]] >= 0) return "the ordering is not a permutation";
    pivot[order_[k]] = k;
  }
  const size_t nt = num_tiles_;
  std::vector<char> stored(nt * nt, 0);  // lower tiles (i >= j) of the factor
  for (size_t j = 0; j < nt; ++j) stored[j * nt + j] = 1;
  column_start_.assign(column_start, column_start + n + 1);
  // Entry e of column c at (a, b) of the permuted lower triangle.
  auto permuted = [&](int64_t e, int64_t c) {
    return std::make_pair(std::max(pivot[row[e]], pivot[c]), std::min(pivot[row[e]], pivot[c]));
  };
  for (int64_t c = 0; c < n; ++c)
    for (int64_t e = column_start[c]; e < column_start[c + 1]; ++e) {
      if (row[e] < 0 || row[e] >= n) return "a row index is out of range";
      if (row[e] < c) continue;
      const auto [a, b] = permuted(e, c);
      stored[a / tile * nt + b / tile] = 1;
    }
  // The block symbolic factorisation: L_ik and L_jk fill L_ij.
  below_.assign(nt, {});
  std::vector<std::vector<int>> sources(nt * nt);
  for (size_t k = 0; k < nt; ++k) {
    for (size_t i = k + 1; i < nt; ++i)
      if (stored[i * nt + k]) below_[k].push_back(static_cast<int>(i));
    for (size_t a = 0; a < below_[k].size(); ++a)
      for (size_t b = 0; b <= a; ++b) {
        stored[below_[k][a] * nt + below_[k][b]] = 1;
        sources[below_[k][a] * nt + below_[k][b]].push_back(static_cast<int>(k));
      }
  }
  tile_id_.assign(nt * nt, -1);
  tiles_.clear();
  sources_.clear();
  int64_t size = 0;
  for (size_t j = 0; j < nt; ++j)
    for (size_t i = j; i < nt; ++i)
      if (stored[i * nt + j]) {
        tile_id_[i * nt + j] = static_cast<int>(tiles_.size());
        tiles_.push_back({static_cast<int>(i), static_cast<int>(j), size});
        sources_.push_back(std::move(sources[i * nt + j]));
        size += static_cast<int64_t>(Rows(static_cast<int>(i))) * Rows(static_cast<int>(j));
      }
  storage_.assign(size, 0.0);
  flops_ = 0;
  for (size_t t = 0; t < tiles_.size(); ++t) {
    const double ri = Rows(tiles_[t].i), rj = Rows(tiles_[t].j);
    for (int k : sources_[t]) flops_ += 2 * ri * rj * Rows(k);
    flops_ += tiles_[t].i == tiles_[t].j ? rj * rj * rj / 3 : ri * rj * rj;
  }
  destination_.assign(column_start[n], -1);
  for (int64_t c = 0; c < n; ++c)
    for (int64_t e = column_start[c]; e < column_start[c + 1]; ++e) {
      if (row[e] < c) continue;
      const auto [a, b] = permuted(e, c);
      const int i = static_cast<int>(a / tile), j = static_cast<int>(b / tile);
      destination_[e] = Index(i, j) + (b % tile) * Rows(i) + a % tile;
    }
  return "";
}

bool TiledCholesky::Factorize(const double* values, int threads) {
  const int64_t chunk = 1 << 16;
  ParallelFor(static_cast<int>((storage_.size() + chunk - 1) / chunk), threads, 1, [&](int c) {
    const int64_t begin = c * chunk, end = std::min<int64_t>(storage_.size(), begin + chunk);
    std::fill(storage_.begin() + begin, storage_.begin() + end, 0.0);
  });
  ParallelFor(static_cast<int>(n_), threads, 256, [&](int c) {
    for (int64_t e = column_start_[c]; e < column_start_[c + 1]; ++e)
      if (destination_[e] >= 0) storage_[destination_[e]] += values[e];
  });
  // Every tile in column-major order, each by one thread: its updates
  // A_ij -= L_ik L_jk^T in ascending k as their sources are final, then its
  // Cholesky (i == j) or its triangular solve against L_jj. A tile waits only
  // for tiles before it in that order, all claimed already: no deadlock.
  const int count = static_cast<int>(tiles_.size());
  std::unique_ptr<std::atomic<bool>[]> final(new std::atomic<bool>[count]);
  for (int t = 0; t < count; ++t) final[t] = false;
  std::atomic<bool> failed{false};
  std::mutex mutex;
  std::condition_variable finished;
  auto wait = [&](int t) {
    if (final[t].load(std::memory_order_acquire)) return;
    std::unique_lock<std::mutex> lock(mutex);
    finished.wait(lock, [&] { return final[t].load(std::memory_order_acquire); });
  };
  ParallelFor(count, threads, 1, [&](int t) {
    const int i = tiles_[t].i, j = tiles_[t].j;
    Map Aij(Tile(i, j), Rows(i), Rows(j));
    for (int k : sources_[t]) {
      wait(TileId(i, k));
      wait(TileId(j, k));
      if (failed) break;
      Aij.noalias() -= ConstMap(Tile(i, k), Rows(i), Rows(k)) * ConstMap(Tile(j, k), Rows(j), Rows(k)).transpose();
    }
    if (i == j && !failed) {
      Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt(Aij);  // in place, lower
      bool ok = llt.info() == Eigen::Success;
      for (int a = 0; a < Rows(j) && ok; ++a) ok = std::isfinite(Aij(a, a)) && Aij(a, a) > 0;
      if (!ok) failed = true;
    } else if (!failed) {
      wait(TileId(j, j));
      ConstMap(Tile(j, j), Rows(j), Rows(j)).transpose().triangularView<Eigen::Upper>().solveInPlace<Eigen::OnTheRight>(Aij);
    }
    {
      std::lock_guard<std::mutex> lock(mutex);
      final[t].store(true, std::memory_order_release);
    }
    finished.notify_all();
  });
  return !failed;
}

void TiledCholesky::Solve(const double* b, double* x) const {
  Eigen::VectorXd y(n_);
  for (int64_t k = 0; k < n_; ++k) y[k] = b[order_[k]];
  for (int j = 0; j < num_tiles_; ++j) {  // L y' = y
    auto yj = y.segment(static_cast<int64_t>(j) * tile_, Rows(j));
    ConstMap(Tile(j, j), Rows(j), Rows(j)).triangularView<Eigen::Lower>().solveInPlace(yj);
    for (int i : below_[j])
      y.segment(static_cast<int64_t>(i) * tile_, Rows(i)).noalias() -= ConstMap(Tile(i, j), Rows(i), Rows(j)) * yj;
  }
  for (int j = num_tiles_ - 1; j >= 0; --j) {  // L^T y'' = y'
    auto yj = y.segment(static_cast<int64_t>(j) * tile_, Rows(j));
    for (int i : below_[j])
      yj.noalias() -= ConstMap(Tile(i, j), Rows(i), Rows(j)).transpose() * y.segment(static_cast<int64_t>(i) * tile_, Rows(i));
    ConstMap(Tile(j, j), Rows(j), Rows(j)).transpose().triangularView<Eigen::Upper>().solveInPlace(yj);
  }
  for (int64_t k = 0; k < n_; ++k) x[order_[k]] = y[k];
}

}  // namespace locforge::sfm

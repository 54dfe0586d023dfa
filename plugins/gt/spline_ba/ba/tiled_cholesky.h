// A Cholesky factorisation of a sparse symmetric positive definite matrix
// in dense square tiles, factorised by every thread it is given.
//
// Why (issue 40, docs/results/cost-model.md): the reduced camera system of a
// floor's bundle adjustment fills in to 70-80 % of a dense triangle, and
// CHOLMOD on Debian's single-threaded ATLAS factorises it on one thread, the
// one serial part of SolveSchurLM left. Here the matrix, permuted by a
// fill-reducing ordering, is cut into tiles of `tile` x `tile`; a tile of the
// factor that stays zero is neither stored nor touched (its pattern is the
// block symbolic factorisation of the tiles' pattern), and the others are
// factorised tile by tile (the tiled Cholesky of Buttari et al., "A class of
// parallel tiled linear algebra algorithms for multicore architectures",
// Parallel Computing 2009, left-looking and skipping zero tiles): each tile, on one
// thread, takes its updates A_ij -= L_ik L_jk^T as the tiles of the columns
// k < j become final, then its Cholesky (a diagonal tile) or its triangular
// solve against L_jj. The threads claim tiles in column order and wait only
// on earlier ones, so column j+1 starts while column j finishes (no barrier
// per column). A tile takes its updates in ascending k on whichever thread,
// so the factor is the same bits at any thread count.
#ifndef LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_TILED_CHOLESKY_H_
#define LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_TILED_CHOLESKY_H_

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

namespace locforge::sfm {

class TiledCholesky {
 public:
  // The matrix's pattern: its lower triangle by columns (CSC; entries above
  // the diagonal are ignored, each (row, column) at most once), n x n, and
  // a fill-reducing ordering (`order[k]`: the original index of the k-th
  // pivot, a permutation of [0, n)). "" or why the pattern is unusable.
  std::string Analyze(int64_t n, const int64_t* column_start, const int64_t* row, const int64_t* order, int tile);

  // Factorises the matrix with these values (in the pattern's order) on
  // `threads` threads; false when it is not positive definite (or not finite).
  bool Factorize(const double* values, int threads);

  // x = A^-1 b after a successful Factorize (x and b may be the same array).
  void Solve(const double* b, double* x) const;

  int64_t stored_values() const { return static_cast<int64_t>(storage_.size()); }
  double flops() const { return flops_; }  // of one factorisation (a multiply-add counts 2)
  int64_t dense_values() const { return num_tiles_ * (num_tiles_ + 1) / 2 * tile_ * tile_; }

 private:
  int Rows(int t) const { return static_cast<int>(std::min<int64_t>(tile_, n_ - static_cast<int64_t>(t) * tile_)); }
  int TileId(int i, int j) const { return tile_id_[static_cast<size_t>(i) * num_tiles_ + j]; }
  int64_t Index(int i, int j) const { return tiles_[TileId(i, j)].offset; }
  double* Tile(int i, int j) { return storage_.data() + Index(i, j); }
  const double* Tile(int i, int j) const { return storage_.data() + Index(i, j); }

  int64_t n_ = 0;
  int tile_ = 0, num_tiles_ = 0;
  double flops_ = 0;
  std::vector<int64_t> order_;              // pivot k -> original index
  std::vector<std::vector<int>> below_;     // by tile column j: the tile rows i > j with L_ij stored
  std::vector<int> tile_id_;                // (i, j) -> index in tiles_, -1: zero
  struct StoredTile {
    int i, j;
    int64_t offset;  // of its values in storage_ (column-major)
  };
  std::vector<StoredTile> tiles_;           // column-major
  std::vector<std::vector<int>> sources_;   // by stored tile (i, j): the k < j with L_ik and L_jk stored
  std::vector<int64_t> destination_;        // by pattern entry: its offset in storage_, -1: ignored
  std::vector<int64_t> column_start_;       // the pattern's columns (for the scatter)
  std::vector<double> storage_;
};

}  // namespace locforge::sfm

#endif  // LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_TILED_CHOLESKY_H_

// See nearest_avx2.h. The scan is a matrix product a * b^T shaped like a GEMM
// micro-kernel (Goto & van de Geijn, "Anatomy of high-performance matrix
// multiplication", 2008): b is packed once in panels of 16 rows, stored
// dimension-major, so one step k of a 6 x 16 tile is 2 loads of b, 6
// broadcasts of a and 12 FMAs into 12 accumulators whose lanes are columns.
// No horizontal sums; the tile's 96 similarities update the running results
// with vector maxima (columns) and a per-row test that skips rows the tile
// cannot change (most of them once the scan is under way).
#include "nearest_avx2.h"

#include <immintrin.h>

#include <limits>
#include <vector>

namespace locforge::matching::avx2 {

bool Supported() { return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"); }

namespace {

constexpr int kRows = 6;          // rows of a per tile
constexpr int kCols = 16;         // rows of b per tile (two 8-lane registers)
constexpr int64_t kChunk = 1020;  // rows of a per pass (x 128 floats = 510 kB: stays in L2)

// panels[p][k][c] = b[16 p + c][k]; rows past m are zeros.
std::vector<float> PackPanels(const float* b, int64_t m, int64_t dims) {
  const int64_t panels = (m + kCols - 1) / kCols;
  std::vector<float> packed(static_cast<size_t>(panels * dims * kCols), 0.f);
  for (int64_t j = 0; j < m; ++j) {
    float* panel = packed.data() + (j / kCols) * dims * kCols + j % kCols;
    for (int64_t k = 0; k < dims; ++k) panel[k * kCols] = b[j * dims + k];
  }
  return packed;
}

// sim[r][h] = rows[r] . (columns 8h..8h+7 of the panel), for 6 rows and 16
// columns. Local accumulators, written out once: through the array the
// compiler stores them on every step.
__attribute__((target("avx2,fma"))) inline void Tile(const float* const rows[kRows], const float* panel,
                                                     int64_t dims, __m256 sim[kRows][2]) {
  const float *a0 = rows[0], *a1 = rows[1], *a2 = rows[2], *a3 = rows[3], *a4 = rows[4], *a5 = rows[5];
  __m256 s00 = _mm256_setzero_ps(), s01 = s00, s10 = s00, s11 = s00, s20 = s00, s21 = s00;
  __m256 s30 = s00, s31 = s00, s40 = s00, s41 = s00, s50 = s00, s51 = s00;
  for (int64_t k = 0; k < dims; ++k, panel += kCols) {
    const __m256 b0 = _mm256_loadu_ps(panel), b1 = _mm256_loadu_ps(panel + 8);
    __m256 x = _mm256_broadcast_ss(a0 + k);
    s00 = _mm256_fmadd_ps(x, b0, s00), s01 = _mm256_fmadd_ps(x, b1, s01);
    x = _mm256_broadcast_ss(a1 + k);
    s10 = _mm256_fmadd_ps(x, b0, s10), s11 = _mm256_fmadd_ps(x, b1, s11);
    x = _mm256_broadcast_ss(a2 + k);
    s20 = _mm256_fmadd_ps(x, b0, s20), s21 = _mm256_fmadd_ps(x, b1, s21);
    x = _mm256_broadcast_ss(a3 + k);
    s30 = _mm256_fmadd_ps(x, b0, s30), s31 = _mm256_fmadd_ps(x, b1, s31);
    x = _mm256_broadcast_ss(a4 + k);
    s40 = _mm256_fmadd_ps(x, b0, s40), s41 = _mm256_fmadd_ps(x, b1, s41);
    x = _mm256_broadcast_ss(a5 + k);
    s50 = _mm256_fmadd_ps(x, b0, s50), s51 = _mm256_fmadd_ps(x, b1, s51);
  }
  sim[0][0] = s00, sim[0][1] = s01, sim[1][0] = s10, sim[1][1] = s11, sim[2][0] = s20, sim[2][1] = s21;
  sim[3][0] = s30, sim[3][1] = s31, sim[4][0] = s40, sim[4][1] = s41, sim[5][0] = s50, sim[5][1] = s51;
}

__attribute__((target("avx2,fma"))) inline float Max(__m256 v) {
  __m128 s = _mm_max_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  s = _mm_max_ps(s, _mm_movehl_ps(s, s));
  return _mm_cvtss_f32(_mm_max_ss(s, _mm_shuffle_ps(s, s, 1)));
}

}  // namespace

__attribute__((target("avx2,fma"))) void ScanNearest(const float* a, int64_t n, const float* b, int64_t m,
                                                     int64_t dims, int* best, float* best_sim, float* second_sim,
                                                     int* col_best, float* col_best_sim) {
  const std::vector<float> panels = PackPanels(b, m, dims);
  const int64_t padded_m = (m + kCols - 1) / kCols * kCols;
  // The columns' running results, padded to whole panels (lanes past m are never read back).
  std::vector<float> col_sim(col_best_sim, col_best_sim + m);
  std::vector<int> col_row(col_best, col_best + m);
  col_sim.resize(padded_m, -std::numeric_limits<float>::infinity());
  col_row.resize(padded_m, -1);
  const std::vector<float> zero_row(dims, 0.f);
  alignas(32) float sims[kRows][kCols];
  // Order: chunks of a ascending, panels ascending, rows ascending. Every row
  // sees its columns ascending and every column its rows ascending, so the
  // strict comparisons keep the lowest index on ties, as the Eigen scan does.
  for (int64_t chunk = 0; chunk < n; chunk += kChunk) {
    const int64_t chunk_end = chunk + kChunk < n ? chunk + kChunk : n;
    for (int64_t j0 = 0; j0 < m; j0 += kCols) {
      const float* panel = panels.data() + j0 * dims;
      const int cols = static_cast<int>(m - j0 < kCols ? m - j0 : kCols);
      for (int64_t i0 = chunk; i0 < chunk_end; i0 += kRows) {
        const int rows_here = static_cast<int>(chunk_end - i0 < kRows ? chunk_end - i0 : kRows);
        const float* rows[kRows];
        for (int r = 0; r < kRows; ++r) rows[r] = r < rows_here ? a + (i0 + r) * dims : zero_row.data();
        __m256 sim[kRows][2];
        Tile(rows, panel, dims, sim);
        // Columns: the tile's best row per lane (first on ties), then into the running best.
        for (int h = 0; h < 2; ++h) {
          __m256 top = sim[0][h];
          __m256i top_row = _mm256_set1_epi32(static_cast<int>(i0));
          for (int r = 1; r < rows_here; ++r) {
            const __m256 better = _mm256_cmp_ps(sim[r][h], top, _CMP_GT_OQ);
            top = _mm256_blendv_ps(top, sim[r][h], better);
            top_row = _mm256_castps_si256(_mm256_blendv_ps(
                _mm256_castsi256_ps(top_row), _mm256_castsi256_ps(_mm256_set1_epi32(static_cast<int>(i0 + r))), better));
          }
          float* running = col_sim.data() + j0 + 8 * h;
          int* running_row = col_row.data() + j0 + 8 * h;
          const __m256 old = _mm256_loadu_ps(running);
          const __m256 better = _mm256_cmp_ps(top, old, _CMP_GT_OQ);
          _mm256_storeu_ps(running, _mm256_blendv_ps(old, top, better));
          const __m256 old_row = _mm256_loadu_ps(reinterpret_cast<const float*>(running_row));
          _mm256_storeu_ps(reinterpret_cast<float*>(running_row),
                           _mm256_blendv_ps(old_row, _mm256_castsi256_ps(top_row), better));
        }
        // Rows: only a row whose second best the tile beats can change.
        for (int r = 0; r < rows_here; ++r) {
          const int64_t i = i0 + r;
          if (!(Max(_mm256_max_ps(sim[r][0], sim[r][1])) > second_sim[i])) continue;
          _mm256_store_ps(sims[r], sim[r][0]);
          _mm256_store_ps(sims[r] + 8, sim[r][1]);
          for (int c = 0; c < cols; ++c) UpdateRow(i, j0 + c, sims[r][c], best, best_sim, second_sim);
        }
      }
    }
  }
  for (int64_t j = 0; j < m; ++j) {
    col_best_sim[j] = col_sim[j];
    col_best[j] = col_row[j];
  }
}

}  // namespace locforge::matching::avx2

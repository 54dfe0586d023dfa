// The scan shared by the SIMD nearest-neighbour kernels (nearest_avx2.cc for
// float descriptors, nearest_vnni.cc for bytes): a matrix product a * b^T
// shaped like a GEMM micro-kernel (Goto & van de Geijn, "Anatomy of
// high-performance matrix multiplication", 2008). b is packed once in panels
// of kCols rows; a kernel makes one kRows x kCols tile of similarities in
// registers; the tile updates the columns' running nearest with vector maxima
// and only the rows whose second nearest it beats (most rows, once the scan is
// under way, skip). Internal to those two files; every function here is
// compiled for AVX2 + FMA by attribute and is only reached after a run-time check.
#ifndef LOCFORGE_PLUGINS_COMMON_MATCHING_NEAREST_TILE_H_
#define LOCFORGE_PLUGINS_COMMON_MATCHING_NEAREST_TILE_H_

#include <immintrin.h>

#include <cstdint>
#include <limits>
#include <vector>

#include "nearest_avx2.h"
#include "nearest_band.h"

namespace locforge::matching::simd {

constexpr int kRows = 6;          // rows of a per tile
constexpr int64_t kChunk = 1020;  // rows of a per pass (x 128 floats = 510 kB: stays in L2)

__attribute__((target("avx2,fma"))) inline float Max(__m256 v) {
  __m128 s = _mm_max_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  s = _mm_max_ps(s, _mm_movehl_ps(s, s));
  return _mm_cvtss_f32(_mm_max_ss(s, _mm_shuffle_ps(s, s, 1)));
}

// One tile's similarities into the running results: the columns' best row
// (first on ties) by vector maxima, then the rows whose second best it beats.
__attribute__((target("avx2,fma"))) inline void UpdateFromTile(__m256 sim[kRows][2], int64_t i0, int rows_here,
                                                               int64_t j0, int cols, float* col_sim, int* col_row,
                                                               int* best, float* best_sim, float* second_sim) {
  for (int h = 0; h < 2; ++h) {
    __m256 top = sim[0][h];
    __m256i top_row = _mm256_set1_epi32(static_cast<int>(i0));
    for (int r = 1; r < rows_here; ++r) {
      const __m256 better = _mm256_cmp_ps(sim[r][h], top, _CMP_GT_OQ);
      top = _mm256_blendv_ps(top, sim[r][h], better);
      top_row = _mm256_castps_si256(_mm256_blendv_ps(
          _mm256_castsi256_ps(top_row), _mm256_castsi256_ps(_mm256_set1_epi32(static_cast<int>(i0 + r))), better));
    }
    float* running = col_sim + j0 + 8 * h;
    int* running_row = col_row + j0 + 8 * h;
    const __m256 old = _mm256_loadu_ps(running);
    const __m256 better = _mm256_cmp_ps(top, old, _CMP_GT_OQ);
    _mm256_storeu_ps(running, _mm256_blendv_ps(old, top, better));
    const __m256 old_row = _mm256_loadu_ps(reinterpret_cast<const float*>(running_row));
    _mm256_storeu_ps(reinterpret_cast<float*>(running_row),
                     _mm256_blendv_ps(old_row, _mm256_castsi256_ps(top_row), better));
  }
  alignas(32) float sims[kCols];
  for (int r = 0; r < rows_here; ++r) {
    const int64_t i = i0 + r;
    if (!(Max(_mm256_max_ps(sim[r][0], sim[r][1])) > second_sim[i])) continue;
    _mm256_store_ps(sims, sim[r][0]);
    _mm256_store_ps(sims + 8, sim[r][1]);
    for (int c = 0; c < cols; ++c) avx2::UpdateRow(i, j0 + c, sims[c], best, best_sim, second_sim);
  }
}

// Similarities of a tile outside the band set to -infinity: never a nearest,
// never a second nearest.
__attribute__((target("avx2,fma"))) inline void MaskTile(const BandArrays& band, int64_t i0, int rows_here,
                                                         int64_t j0, __m256 sim[kRows][2]) {
  const __m256 none = _mm256_set1_ps(-std::numeric_limits<float>::infinity()), t2 = _mm256_set1_ps(band.t2);
  for (int h = 0; h < 2; ++h) {
    const int64_t j = j0 + 8 * h;
    const __m256 cx = _mm256_loadu_ps(band.cx + j), cy = _mm256_loadu_ps(band.cy + j);
    const __m256 cz = _mm256_loadu_ps(band.cz + j), col_den = _mm256_loadu_ps(band.col_den + j);
    for (int r = 0; r < rows_here; ++r) {
      const int64_t i = i0 + r;
      const __m256 num = _mm256_add_ps(
          _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(band.lx[i]), cx), _mm256_mul_ps(_mm256_set1_ps(band.ly[i]), cy)),
          _mm256_mul_ps(_mm256_set1_ps(band.lz[i]), cz));
      const __m256 bound = _mm256_mul_ps(t2, _mm256_add_ps(_mm256_set1_ps(band.row_den[i]), col_den));
      const __m256 inside = _mm256_cmp_ps(_mm256_mul_ps(num, num), bound, _CMP_LE_OQ);
      sim[r][h] = _mm256_blendv_ps(none, sim[r][h], inside);
    }
  }
}

// The scan over n rows of a and m rows of b. kernel(i0, rows_here, j0, sim)
// fills the similarities of rows i0.. (rows_here of them; the others are
// ignored) and the kCols columns from j0 (columns past m too: they are never
// read back); with a band, the tile is then masked to it. Order: chunks of a ascending, panels ascending, rows ascending,
// so every row sees its columns ascending and every column its rows
// ascending: the strict comparisons keep the lowest index on ties, as the
// portable scans do.
template <class Kernel>
__attribute__((target("avx2,fma"))) void ScanTiles(int64_t n, int64_t m, const Kernel& kernel, const BandArrays* band,
                                                   int* best, float* best_sim, float* second_sim, int* col_best,
                                                   float* col_best_sim) {
  const int64_t padded_m = PanelPadded(m);
  // The columns' running results, padded to whole panels.
  std::vector<float> col_sim(col_best_sim, col_best_sim + m);
  std::vector<int> col_row(col_best, col_best + m);
  col_sim.resize(padded_m, -std::numeric_limits<float>::infinity());
  col_row.resize(padded_m, -1);
  for (int64_t chunk = 0; chunk < n; chunk += kChunk) {
    const int64_t chunk_end = chunk + kChunk < n ? chunk + kChunk : n;
    for (int64_t j0 = 0; j0 < m; j0 += kCols) {
      const int cols = static_cast<int>(m - j0 < kCols ? m - j0 : kCols);
      for (int64_t i0 = chunk; i0 < chunk_end; i0 += kRows) {
        const int rows_here = static_cast<int>(chunk_end - i0 < kRows ? chunk_end - i0 : kRows);
        __m256 sim[kRows][2];
        kernel(i0, rows_here, j0, sim);
        if (band) MaskTile(*band, i0, rows_here, j0, sim);
        UpdateFromTile(sim, i0, rows_here, j0, cols, col_sim.data(), col_row.data(), best, best_sim, second_sim);
      }
    }
  }
  for (int64_t j = 0; j < m; ++j) {
    col_best_sim[j] = col_sim[j];
    col_best[j] = col_row[j];
  }
}

}  // namespace locforge::matching::simd

#endif  // LOCFORGE_PLUGINS_COMMON_MATCHING_NEAREST_TILE_H_

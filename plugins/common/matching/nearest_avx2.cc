// See nearest_avx2.h. The float kernel of the tiled scan (nearest_tile.h): b
// packed in panels of 16 rows stored dimension-major, so one step k of a
// 6 x 16 tile is 2 loads of b, 6 broadcasts of a and 12 FMAs into 12
// accumulators whose lanes are columns; no horizontal sums.
#include "nearest_avx2.h"

#include "nearest_tile.h"

namespace locforge::matching::avx2 {

bool Supported() { return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"); }

namespace {

using simd::kCols;
using simd::kRows;

// panels[p][k][c] = b[16 p + c][k]; rows past m are zeros.
std::vector<float> PackPanels(const float* b, int64_t m, int64_t dims) {
  const int64_t panels = simd::PanelPadded(m) / kCols;
  std::vector<float> packed(static_cast<size_t>(panels * dims * kCols), 0.f);
  for (int64_t j = 0; j < m; ++j) {
    float* panel = packed.data() + (j / kCols) * dims * kCols + j % kCols;
    for (int64_t k = 0; k < dims; ++k) panel[k * kCols] = b[j * dims + k];
  }
  return packed;
}

struct FloatKernel {
  const float* a;
  int64_t dims;
  std::vector<float> panels;
  std::vector<float> zero_row;

  // sim[r][h] = row i0 + r of a . (columns j0 + 8h .. j0 + 8h + 7). Local
  // accumulators, written out once: through the array the compiler stores
  // them on every step.
  __attribute__((target("avx2,fma"))) void operator()(int64_t i0, int rows_here, int64_t j0,
                                                      __m256 sim[kRows][2]) const {
    const float* rows[kRows];
    for (int r = 0; r < kRows; ++r) rows[r] = r < rows_here ? a + (i0 + r) * dims : zero_row.data();
    const float* panel = panels.data() + j0 * dims;
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
};

// Byte values held as floats: the float tiles give their exact dot products
// (every partial sum an integer below 2^24), made similarities as
// vnni::ByteSimilarity makes them.
struct ScaledKernel {
  FloatKernel dots;
  const float* inv_norm_a;
  std::vector<float> inv_norm_b;  // padded to whole panels with zeros

  __attribute__((target("avx2,fma"))) void operator()(int64_t i0, int rows_here, int64_t j0,
                                                      __m256 sim[kRows][2]) const {
    dots(i0, rows_here, j0, sim);
    const __m256 inv_b[2] = {_mm256_loadu_ps(inv_norm_b.data() + j0), _mm256_loadu_ps(inv_norm_b.data() + j0 + 8)};
    for (int r = 0; r < kRows; ++r) {
      const __m256 inv_a = _mm256_set1_ps(r < rows_here ? inv_norm_a[i0 + r] : 0.f);
      for (int h = 0; h < 2; ++h) sim[r][h] = _mm256_mul_ps(_mm256_mul_ps(sim[r][h], inv_b[h]), inv_a);
    }
  }
};

}  // namespace

void ScanNearestScaled(const float* a, int64_t n, const float* inv_norm_a, const float* b, int64_t m,
                       const float* inv_norm_b, int64_t dims, const simd::BandArrays* band, int* best,
                       float* best_sim, float* second_sim, int* col_best, float* col_best_sim) {
  const ScaledKernel kernel{{a, dims, PackPanels(b, m, dims), std::vector<float>(dims, 0.f)}, inv_norm_a,
                            simd::PaddedToPanels(inv_norm_b, m)};
  simd::ScanTiles(n, m, kernel, band, best, best_sim, second_sim, col_best, col_best_sim);
}

void ScanNearest(const float* a, int64_t n, const float* b, int64_t m, int64_t dims, const simd::BandArrays* band,
                 int* best, float* best_sim, float* second_sim, int* col_best, float* col_best_sim) {
  const FloatKernel kernel{a, dims, PackPanels(b, m, dims), std::vector<float>(dims, 0.f)};
  simd::ScanTiles(n, m, kernel, band, best, best_sim, second_sim, col_best, col_best_sim);
}

}  // namespace locforge::matching::avx2

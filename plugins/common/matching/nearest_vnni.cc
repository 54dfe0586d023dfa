// See nearest_vnni.h. The byte kernel of the tiled scan (nearest_tile.h).
// VPDPBUSD multiplies unsigned bytes by signed ones, four adjacent pairs into
// each 32-bit lane. b is stored shifted, b - 128 (signed), and the shift is
// added back per row of a: a . b = a . (b - 128) + 128 * sum(a), exact in
// int32 for dims up to 65 536 (matching.cc checks). One step of a 6 x 16 tile covers 4
// dimensions: 2 loads of b, 6 broadcasts of 4 bytes of a, 12 VPDPBUSD.
#include "nearest_vnni.h"

#include <cstring>

#include "nearest_tile.h"

namespace locforge::matching::vnni {

bool Supported() {
  return avx2::Supported() && __builtin_cpu_supports("avx512vnni") && __builtin_cpu_supports("avx512vl");
}

namespace {

using simd::kCols;
using simd::kRows;

// panels[p][q][c][0..3] = b[16 p + c][4 q .. 4 q + 3] - 128; rows past m are
// zero bytes (-128 shifted), their lanes never read back.
std::vector<int8_t> PackPanels(const uint8_t* b, int64_t m, int64_t dims) {
  const int64_t panels = simd::PanelPadded(m) / kCols;
  std::vector<int8_t> packed(static_cast<size_t>(panels * dims * kCols), static_cast<int8_t>(-128));
  for (int64_t j = 0; j < m; ++j) {
    int8_t* panel = packed.data() + (j / kCols) * dims * kCols + (j % kCols) * 4;
    for (int64_t k = 0; k < dims; ++k)
      panel[(k / 4) * 4 * kCols + k % 4] = static_cast<int8_t>(static_cast<int>(b[j * dims + k]) - 128);
  }
  return packed;
}

struct ByteKernel {
  const uint8_t* a;
  int64_t dims;
  const float* inv_norm_a;
  std::vector<int8_t> panels;
  std::vector<float> inv_norm_b;  // padded to whole panels with zeros
  std::vector<int32_t> shift_a;   // 128 * sum(a row)
  std::vector<uint8_t> zero_row;

  __attribute__((target("avx512vnni,avx512vl,avx2,fma"))) void operator()(int64_t i0, int rows_here, int64_t j0,
                                                                          __m256 sim[kRows][2]) const {
    const uint8_t* rows[kRows];
    for (int r = 0; r < kRows; ++r) rows[r] = r < rows_here ? a + (i0 + r) * dims : zero_row.data();
    const int8_t* panel = panels.data() + j0 * dims;
    auto quad = [](const uint8_t* p) {
      int32_t v;
      std::memcpy(&v, p, 4);
      return v;
    };
    __m256i s00 = _mm256_setzero_si256(), s01 = s00, s10 = s00, s11 = s00, s20 = s00, s21 = s00;
    __m256i s30 = s00, s31 = s00, s40 = s00, s41 = s00, s50 = s00, s51 = s00;
    for (int64_t k = 0; k < dims; k += 4, panel += 4 * kCols) {
      const __m256i b0 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(panel));
      const __m256i b1 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(panel + 32));
      __m256i x = _mm256_set1_epi32(quad(rows[0] + k));
      s00 = _mm256_dpbusd_epi32(s00, x, b0), s01 = _mm256_dpbusd_epi32(s01, x, b1);
      x = _mm256_set1_epi32(quad(rows[1] + k));
      s10 = _mm256_dpbusd_epi32(s10, x, b0), s11 = _mm256_dpbusd_epi32(s11, x, b1);
      x = _mm256_set1_epi32(quad(rows[2] + k));
      s20 = _mm256_dpbusd_epi32(s20, x, b0), s21 = _mm256_dpbusd_epi32(s21, x, b1);
      x = _mm256_set1_epi32(quad(rows[3] + k));
      s30 = _mm256_dpbusd_epi32(s30, x, b0), s31 = _mm256_dpbusd_epi32(s31, x, b1);
      x = _mm256_set1_epi32(quad(rows[4] + k));
      s40 = _mm256_dpbusd_epi32(s40, x, b0), s41 = _mm256_dpbusd_epi32(s41, x, b1);
      x = _mm256_set1_epi32(quad(rows[5] + k));
      s50 = _mm256_dpbusd_epi32(s50, x, b0), s51 = _mm256_dpbusd_epi32(s51, x, b1);
    }
    const __m256i dots[kRows][2] = {{s00, s01}, {s10, s11}, {s20, s21}, {s30, s31}, {s40, s41}, {s50, s51}};
    const __m256 inv_b[2] = {_mm256_loadu_ps(inv_norm_b.data() + j0), _mm256_loadu_ps(inv_norm_b.data() + j0 + 8)};
    for (int r = 0; r < kRows; ++r) {
      const bool real = r < rows_here;
      const __m256i shift = _mm256_set1_epi32(real ? shift_a[i0 + r] : 0);
      const __m256 inv_a = _mm256_set1_ps(real ? inv_norm_a[i0 + r] : 0.f);
      for (int h = 0; h < 2; ++h)  // ByteSimilarity, lane by lane
        sim[r][h] = _mm256_mul_ps(_mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_add_epi32(dots[r][h], shift)), inv_b[h]),
                                  inv_a);
    }
  }
};

}  // namespace

void ScanNearest(const uint8_t* a, int64_t n, const float* inv_norm_a, const uint8_t* b, int64_t m,
                 const float* inv_norm_b, int64_t dims, const simd::BandArrays* band, int* best, float* best_sim,
                 float* second_sim, int* col_best, float* col_best_sim) {
  ByteKernel kernel{a, dims, inv_norm_a, PackPanels(b, m, dims), simd::PaddedToPanels(inv_norm_b, m), {},
                    std::vector<uint8_t>(dims, 0)};
  kernel.shift_a.resize(n);
  for (int64_t i = 0; i < n; ++i) {
    int32_t sum = 0;
    for (int64_t k = 0; k < dims; ++k) sum += a[i * dims + k];
    kernel.shift_a[i] = 128 * sum;
  }
  simd::ScanTiles(n, m, kernel, band, best, best_sim, second_sim, col_best, col_best_sim);
}

}  // namespace locforge::matching::vnni

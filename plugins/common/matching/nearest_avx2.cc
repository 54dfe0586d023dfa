// See nearest_avx2.h. Blocked dot products: 3 rows of a against 4 rows of b
// in 12 AVX2 accumulators (with the 3 rows of a and one of b: 16 registers),
// b walked in chunks that stay in the L2 cache while every row of a passes.
#include "nearest_avx2.h"

#include <immintrin.h>

namespace locforge::matching::avx2 {

bool Supported() { return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"); }

namespace {

constexpr int64_t kChunk = 384;  // rows of b per pass: 384 x 128 floats = 192 kB

__attribute__((target("avx2,fma"))) inline float Sum(__m256 v) {
  const __m128 s = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  const __m128 h = _mm_add_ps(s, _mm_movehl_ps(s, s));
  return _mm_cvtss_f32(_mm_add_ss(h, _mm_shuffle_ps(h, h, 1)));
}

__attribute__((target("avx2,fma"))) inline float Dot(const float* x, const float* y, int64_t dims) {
  __m256 acc = _mm256_setzero_ps();
  for (int64_t k = 0; k < dims; k += 8) acc = _mm256_fmadd_ps(_mm256_loadu_ps(x + k), _mm256_loadu_ps(y + k), acc);
  return Sum(acc);
}

// s[r][c] = a_r . b_c for 3 rows of a and 4 of b.
__attribute__((target("avx2,fma"))) inline void Dot3x4(const float* a, const float* b, int64_t dims,
                                                       float s[3][4]) {
  __m256 acc[3][4];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) acc[r][c] = _mm256_setzero_ps();
  for (int64_t k = 0; k < dims; k += 8) {
    const __m256 a0 = _mm256_loadu_ps(a + k), a1 = _mm256_loadu_ps(a + dims + k), a2 = _mm256_loadu_ps(a + 2 * dims + k);
    for (int c = 0; c < 4; ++c) {
      const __m256 bc = _mm256_loadu_ps(b + c * dims + k);
      acc[0][c] = _mm256_fmadd_ps(a0, bc, acc[0][c]);
      acc[1][c] = _mm256_fmadd_ps(a1, bc, acc[1][c]);
      acc[2][c] = _mm256_fmadd_ps(a2, bc, acc[2][c]);
    }
  }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) s[r][c] = Sum(acc[r][c]);
}

}  // namespace

__attribute__((target("avx2,fma"))) void ScanNearest(const float* a, int64_t n, const float* b, int64_t m,
                                                     int64_t dims, int* best, float* best_sim, float* second_sim,
                                                     int* col_best, float* col_best_sim) {
  auto update = [&](int64_t i, int64_t j, float s) {
    UpdateNearest(i, j, s, best, best_sim, second_sim, col_best, col_best_sim);
  };
  for (int64_t j0 = 0; j0 < m; j0 += kChunk) {
    const int64_t j1 = j0 + kChunk < m ? j0 + kChunk : m;
    int64_t i = 0;
    for (; i + 3 <= n; i += 3) {
      int64_t j = j0;
      for (; j + 4 <= j1; j += 4) {
        float s[3][4];
        Dot3x4(a + i * dims, b + j * dims, dims, s);
        // Row-major over the block: each row sees its columns ascending, and
        // each column its rows ascending.
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 4; ++c) update(i + r, j + c, s[r][c]);
      }
      for (; j < j1; ++j)
        for (int r = 0; r < 3; ++r) update(i + r, j, Dot(a + (i + r) * dims, b + j * dims, dims));
    }
    for (; i < n; ++i)
      for (int64_t j = j0; j < j1; ++j) update(i, j, Dot(a + i * dims, b + j * dims, dims));
  }
}

}  // namespace locforge::matching::avx2

// The nearest-neighbour scan of MatchDescriptors with AVX2 + FMA, chosen at
// run time (matching.cc) on processors that have them; the Eigen path serves
// the others. nearest_avx2.cc is compiled for the baseline target; only its
// functions marked target("avx2,fma") use AVX2, so nothing it shares with
// other translation units (UpdateRow below, std templates) holds AVX2 code.
#ifndef LOCFORGE_PLUGINS_COMMON_MATCHING_NEAREST_AVX2_H_
#define LOCFORGE_PLUGINS_COMMON_MATCHING_NEAREST_AVX2_H_

#include <cstdint>

#include "nearest_band.h"

namespace locforge::matching::avx2 {

// One similarity s of row i (of a) and row j (of b) into row i's running
// nearest and second nearest. Callers feed each row its columns in ascending
// order, so the strict comparisons keep the lowest index on ties.
inline void UpdateRow(int64_t i, int64_t j, float s, int* best, float* best_sim, float* second_sim) {
  if (s > best_sim[i]) {
    second_sim[i] = best_sim[i];
    best_sim[i] = s;
    best[i] = static_cast<int>(j);
  } else if (s > second_sim[i]) {
    second_sim[i] = s;
  }
}

// The same similarity into column j's running nearest row (rows fed ascending).
inline void UpdateColumn(int64_t i, int64_t j, float s, int* col_best, float* col_best_sim) {
  if (s > col_best_sim[j]) {
    col_best_sim[j] = s;
    col_best[j] = static_cast<int>(i);
  }
}

// True when the processor runs AVX2 and FMA.
bool Supported();

// Rows of `a` (n x dims) and `b` (m x dims), row-major, dims a multiple of 8.
// For each row i of a: its most and second most similar rows of b by dot
// product (best[i], best_sim[i], second_sim[i]); for each row j of b: the row
// of a most similar to it (col_best[j], col_best_sim[j]). Ties keep the lowest
// index, as the Eigen path does. The sims arrays must start at -infinity and
// the index arrays at -1. With a band (may be null), only pairs inside it are
// candidates.
void ScanNearest(const float* a, int64_t n, const float* b, int64_t m, int64_t dims, const simd::BandArrays* band,
                 int* best, float* best_sim, float* second_sim, int* col_best, float* col_best_sim);

// The same scan over byte values held as floats, dims <= 258 so that every
// dot product is an exact integer in float; the similarity of rows i and j is
// vnni::ByteSimilarity(a_i . b_j, inv_norm_a[i], inv_norm_b[j]): the same
// bits as the VNNI and portable byte scans.
void ScanNearestScaled(const float* a, int64_t n, const float* inv_norm_a, const float* b, int64_t m,
                       const float* inv_norm_b, int64_t dims, const simd::BandArrays* band, int* best,
                       float* best_sim, float* second_sim, int* col_best, float* col_best_sim);

}  // namespace locforge::matching::avx2

#endif  // LOCFORGE_PLUGINS_COMMON_MATCHING_NEAREST_AVX2_H_

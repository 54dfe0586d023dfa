// The nearest-neighbour scan of byte descriptors (SIFT's uint8 rows) with
// AVX-512 VNNI on 256-bit registers (VPDPBUSD: 32 byte products per
// instruction where a float FMA makes 8), chosen at run time (matching.cc)
// on processors that have it; compiled for the baseline target, only the
// kernel is marked for VNNI. Dot products of bytes are exact integers, and
// each similarity is made from one by ByteSimilarity, so this scan and the
// portable one (matching.cc) give the same bits.
#ifndef LOCFORGE_PLUGINS_COMMON_MATCHING_NEAREST_VNNI_H_
#define LOCFORGE_PLUGINS_COMMON_MATCHING_NEAREST_VNNI_H_

#include <cstdint>

#include "nearest_band.h"

namespace locforge::matching::vnni {

// The cosine similarity of two byte rows from their exact dot product and
// inverse L2 norms (a dot of up to 258 bytes, < 2^24, is exact as a float).
inline float ByteSimilarity(int32_t dot, float inv_norm_a, float inv_norm_b) {
  return static_cast<float>(dot) * inv_norm_b * inv_norm_a;
}

constexpr int64_t kMaxDims = 65536;
// Dot products of byte rows up to this size are exact in float arithmetic
// (258 x 255^2 < 2^24), whatever the order of the sums.
constexpr int64_t kMaxExactFloatDims = 258;

// True when the processor runs AVX-512 VNNI and VL (and AVX2 + FMA).
bool Supported();

// Rows of `a` (n x dims) and `b` (m x dims) bytes, row-major, dims a multiple
// of 4 and at most kMaxDims (int32 sums stay exact); inv_norm_a / inv_norm_b: 1 / L2 norm of each row (0 for a zero row).
// Results as avx2::ScanNearest (band included), with ByteSimilarity as the similarity.
void ScanNearest(const uint8_t* a, int64_t n, const float* inv_norm_a, const uint8_t* b, int64_t m,
                 const float* inv_norm_b, int64_t dims, const simd::BandArrays* band, int* best, float* best_sim,
                 float* second_sim, int* col_best, float* col_best_sim);

}  // namespace locforge::matching::vnni

#endif  // LOCFORGE_PLUGINS_COMMON_MATCHING_NEAREST_VNNI_H_

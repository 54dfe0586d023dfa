// The nearest-neighbour scan of MatchDescriptors with AVX2 + FMA, chosen at
// run time (matching.cc) on processors that have them; the Eigen path serves
// the others. Plain pointers only: nearest_avx2.cc is compiled with -mavx2
// -mfma and must instantiate no template or inline function that another
// translation unit could share (the linker might keep its AVX2 copy).
#ifndef LOCFORGE_PLUGINS_MATCHING_NEAREST_AVX2_H_
#define LOCFORGE_PLUGINS_MATCHING_NEAREST_AVX2_H_

#include <cstdint>

namespace locforge::matching::avx2 {

// True when the processor runs AVX2 and FMA.
bool Supported();

// Rows of `a` (n x dims) and `b` (m x dims), row-major, dims a multiple of 8.
// For each row i of a: its most and second most similar rows of b by dot
// product (best[i], best_sim[i], second_sim[i]); for each row j of b: the row
// of a most similar to it (col_best[j], col_best_sim[j]). Ties keep the lowest
// index, as the Eigen path does. The sims arrays must start at -infinity and
// the index arrays at -1.
void ScanNearest(const float* a, int64_t n, const float* b, int64_t m, int64_t dims, int* best,
                 float* best_sim, float* second_sim, int* col_best, float* col_best_sim);

}  // namespace locforge::matching::avx2

#endif  // LOCFORGE_PLUGINS_MATCHING_NEAREST_AVX2_H_

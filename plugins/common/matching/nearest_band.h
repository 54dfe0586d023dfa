// The epipolar band of a scan (matching.h, EpipolarBand) in the form the
// scans read it, shared by the SIMD kernels and the portable scans so that
// both decide every pair by the same float operations; and the panel width
// its column arrays are padded to.
#ifndef LOCFORGE_PLUGINS_COMMON_MATCHING_NEAREST_BAND_H_
#define LOCFORGE_PLUGINS_COMMON_MATCHING_NEAREST_BAND_H_

#include <cstdint>
#include <vector>

namespace locforge::matching::simd {

constexpr int kCols = 16;  // rows of b per SIMD panel (two 8-lane registers)

// m rounded up to whole panels: the SIMD scans read per-column arrays by panel.
inline int64_t PanelPadded(int64_t m) { return (m + kCols - 1) / kCols * kCols; }

// v[0..m) followed by zeros up to whole panels.
inline std::vector<float> PaddedToPanels(const float* v, int64_t m) {
  std::vector<float> out(v, v + m);
  out.resize(PanelPadded(m), 0.f);
  return out;
}

// An epipolar band (matching.h, EpipolarBand) as the scans read it: row i
// may match column j only when (c_j . l_i)^2 <= t2 (row_den_i + col_den_j),
// the Sampson distance of the two keypoints to the known epipolar geometry
// at most the band's half width. Column arrays padded to whole panels.
struct BandArrays {
  const float *lx, *ly, *lz, *row_den;  // per row of a: l = E x_a, l0^2 + l1^2
  const float *cx, *cy, *cz, *col_den;  // per column: x_b, (E^T x_b)0^2 + (E^T x_b)1^2
  float t2;                             // squared half width, normalised units
};

// Whether row i and column j are in the band; the same float operations, in
// the same order, as MaskTile's lanes (no fused multiply-add).
inline bool InBand(const BandArrays& band, int64_t i, int64_t j) {
  const float num = band.lx[i] * band.cx[j] + band.ly[i] * band.cy[j] + band.lz[i] * band.cz[j];
  return num * num <= band.t2 * (band.row_den[i] + band.col_den[j]);
}

}  // namespace locforge::matching::simd

#endif  // LOCFORGE_PLUGINS_COMMON_MATCHING_NEAREST_BAND_H_

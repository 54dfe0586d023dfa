// The pixel convention between kapture and COLMAP, stated once.
//
// COLMAP 3.8 keypoints (database `keypoints` blobs and the points2D of a
// model) put the image's top-left corner at (0, 0), so the centre of the
// first pixel is (0.5, 0.5) (camera.h; COLMAP's SIFT adds 0.5 to VLFeat's
// pixel-centre coordinates). kapture keypoints exchanged with COLMAP use the
// same convention: the conversion is the identity, no half-pixel shift.
//
// Evidence (maupertuis, exported by the kapture toolbox, checked by
// database_test.cc and convert_test.cc): for all four images the kapture
// keypoint files reconstruction/keypoints/SIFT/<image>.kpt are byte for byte
// the `keypoints` blobs of colmap/colmap.db (6424, 5920, 5576, 6090 rows of
// 6 float32), and the points2D of colmap/reconstruction/images.txt equal the
// kapture keypoints (to the 6 digits printed); the camera's principal point
// (959.5, 539.5) is width/2, height/2 of the 1919 x 1079 image, COLMAP's
// corner-origin default; kapture's points3d projected with its poses and
// camera land on its keypoints with a mean error of 0.346 px unshifted,
// 0.798 px shifted by +0.5 and 0.792 px by -0.5; our export re-triangulated
// by `colmap point_triangulator` reprojects with 0.358 px.
//
// Extractors that put the first pixel centre at (0, 0) (e.g. some R2D2
// exports) must be shifted by the caller before export; this SDK never
// guesses.
#ifndef LOCFORGE_COLMAP_CONVENTION_H_
#define LOCFORGE_COLMAP_CONVENTION_H_

#include <Eigen/Core>

namespace locforge::colmap {

// COLMAP pixel = kapture pixel + this offset (both axes).
inline constexpr double kColmapMinusKapturePixel = 0.0;

enum class PixelDirection { kKaptureToColmap, kColmapToKapture };

// The one place the convention is applied, in both directions.
template <typename Scalar>
inline Eigen::Matrix<Scalar, 2, 1> ConvertPixel(const Eigen::Matrix<Scalar, 2, 1>& xy,
                                               PixelDirection direction) {
  const Scalar offset = static_cast<Scalar>(
      direction == PixelDirection::kKaptureToColmap ? kColmapMinusKapturePixel
                                                    : -kColmapMinusKapturePixel);
  return xy + Eigen::Matrix<Scalar, 2, 1>::Constant(offset);
}

}  // namespace locforge::colmap

#endif  // LOCFORGE_COLMAP_CONVENTION_H_

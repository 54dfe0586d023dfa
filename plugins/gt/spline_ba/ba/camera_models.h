// Templated COLMAP projection for Ceres autodiff: the same formulas as
// locforge::Camera::Project (sdk/src/core/camera.cc, after COLMAP 3.8's
// camera_models.h): (u, v) = (X/Z, Y/Z), (u, v) += distortion(u, v),
// pixel = (fx u + cx, fy v + cy). Parameter order as COLMAP's.
#ifndef LOCFORGE_SFM_CAMERA_MODELS_H_
#define LOCFORGE_SFM_CAMERA_MODELS_H_

#include <Eigen/Core>

#include "locforge/camera.h"

namespace locforge::sfm {

// Number of parameters of the models the bundle adjuster supports, 0 for
// the others.
constexpr int NumParamsOf(CameraModelId id) {
  switch (id) {
    case CameraModelId::kSimplePinhole: return 3;
    case CameraModelId::kPinhole: return 4;
    case CameraModelId::kSimpleRadial: return 4;
    case CameraModelId::kRadial: return 5;
    case CameraModelId::kOpenCV: return 8;
    default: return 0;
  }
}
inline bool IsSupportedModel(CameraModelId id) { return NumParamsOf(id) > 0; }

// Indices of the principal point (cx, cy) in the parameter vector.
constexpr int PrincipalPointIndex(CameraModelId id) {
  return (id == CameraModelId::kPinhole || id == CameraModelId::kOpenCV) ? 2 : 1;
}

// Point in the camera frame -> pixel. The caller ensures p(2) > 0.
template <CameraModelId kModel, typename T>
void ProjectT(const T* params, const Eigen::Matrix<T, 3, 1>& p, T* xy) {
  const T u = p(0) / p(2);
  const T v = p(1) / p(2);
  T du = T(0), dv = T(0);
  T fx, fy, cx, cy;
  if constexpr (kModel == CameraModelId::kPinhole || kModel == CameraModelId::kOpenCV) {
    fx = params[0];
    fy = params[1];
    cx = params[2];
    cy = params[3];
  } else {
    fx = params[0];
    fy = params[0];
    cx = params[1];
    cy = params[2];
  }
  if constexpr (kModel == CameraModelId::kSimpleRadial) {
    const T radial = params[3] * (u * u + v * v);
    du = u * radial;
    dv = v * radial;
  } else if constexpr (kModel == CameraModelId::kRadial) {
    const T r2 = u * u + v * v;
    const T radial = params[3] * r2 + params[4] * r2 * r2;
    du = u * radial;
    dv = v * radial;
  } else if constexpr (kModel == CameraModelId::kOpenCV) {
    const T k1 = params[4], k2 = params[5], p1 = params[6], p2 = params[7];
    const T u2 = u * u, v2 = v * v, uv = u * v;
    const T r2 = u2 + v2;
    const T radial = k1 * r2 + k2 * r2 * r2;
    du = u * radial + T(2) * p1 * uv + p2 * (r2 + T(2) * u2);
    dv = v * radial + T(2) * p2 * uv + p1 * (r2 + T(2) * v2);
  }
  xy[0] = fx * (u + du) + cx;
  xy[1] = fy * (v + dv) + cy;
}

}  // namespace locforge::sfm

#endif  // LOCFORGE_SFM_CAMERA_MODELS_H_

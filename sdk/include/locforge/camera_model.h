// The COLMAP 3.8 camera models (src/base/camera_models.h) as templates over
// the scalar type: locforge::Camera (camera.h) evaluates them on doubles, the
// bundle adjuster's Ceres cost functions on Jets for automatic derivatives.
// The lens distortion acts on the normalised image plane (u, v) = (X/Z, Y/Z):
// (u, v) += distortion(u, v), then pixel = (fx u + cx, fy v + cy). Parameter
// order as COLMAP's; FOV and THIN_PRISM_FISHEYE, whose distortion is not an
// additive delta of (u, v), are evaluated by Camera only.
#ifndef LOCFORGE_CAMERA_MODEL_H_
#define LOCFORGE_CAMERA_MODEL_H_

#include <cmath>
#include <limits>

#include "locforge/camera.h"

namespace locforge::camera_model {

// Models whose first parameter is a single focal length f (fx = fy = f).
constexpr bool HasSingleFocal(CameraModelId id) {
  return id == CameraModelId::kSimplePinhole || id == CameraModelId::kSimpleRadial ||
         id == CameraModelId::kRadial || id == CameraModelId::kSimpleRadialFisheye ||
         id == CameraModelId::kRadialFisheye;
}
// Index of the first distortion ("extra") parameter.
constexpr int ExtraOffset(CameraModelId id) { return HasSingleFocal(id) ? 3 : 4; }
// Index of the principal point (cx, cy) in the parameter vector.
constexpr int PrincipalPointIndex(CameraModelId id) { return HasSingleFocal(id) ? 1 : 2; }
// Parameter count of the models evaluated by Project (0 for the others).
constexpr int NumParams(CameraModelId id) {
  switch (id) {
    case CameraModelId::kSimplePinhole: return 3;
    case CameraModelId::kPinhole: return 4;
    case CameraModelId::kSimpleRadial: return 4;
    case CameraModelId::kRadial: return 5;
    case CameraModelId::kOpenCV: return 8;
    case CameraModelId::kOpenCVFisheye: return 8;
    case CameraModelId::kFullOpenCV: return 12;
    case CameraModelId::kSimpleRadialFisheye: return 4;
    case CameraModelId::kRadialFisheye: return 5;
    default: return 0;
  }
}

// COLMAP's `Distortion`: the delta (du, dv) a model adds to (u, v); `k`
// points at its first distortion parameter. THIN_PRISM_FISHEYE's acts on the
// equidistant coordinates (Camera::Distort takes them there first).
template <CameraModelId kModel, typename T>
void Distortion(const T* k, const T& u, const T& v, T* du, T* dv) {
  using std::atan;
  using std::sqrt;
  const T u2 = u * u;
  const T v2 = v * v;
  if constexpr (kModel == CameraModelId::kSimpleRadial) {
    const T radial = k[0] * (u2 + v2);
    *du = u * radial;
    *dv = v * radial;
  } else if constexpr (kModel == CameraModelId::kRadial) {
    const T r2 = u2 + v2;
    const T radial = k[0] * r2 + k[1] * r2 * r2;
    *du = u * radial;
    *dv = v * radial;
  } else if constexpr (kModel == CameraModelId::kOpenCV) {
    const T k1 = k[0], k2 = k[1], p1 = k[2], p2 = k[3];
    const T uv = u * v;
    const T r2 = u2 + v2;
    const T radial = k1 * r2 + k2 * r2 * r2;
    *du = u * radial + T(2.0) * p1 * uv + p2 * (r2 + T(2.0) * u2);
    *dv = v * radial + T(2.0) * p2 * uv + p1 * (r2 + T(2.0) * v2);
  } else if constexpr (kModel == CameraModelId::kFullOpenCV) {
    const T k1 = k[0], k2 = k[1], p1 = k[2], p2 = k[3];
    const T k3 = k[4], k4 = k[5], k5 = k[6], k6 = k[7];
    const T uv = u * v;
    const T r2 = u2 + v2;
    const T r4 = r2 * r2;
    const T r6 = r4 * r2;
    const T radial = (T(1.0) + k1 * r2 + k2 * r4 + k3 * r6) / (T(1.0) + k4 * r2 + k5 * r4 + k6 * r6);
    *du = u * radial + T(2.0) * p1 * uv + p2 * (r2 + T(2.0) * u2) - u;
    *dv = v * radial + T(2.0) * p2 * uv + p1 * (r2 + T(2.0) * v2) - v;
  } else if constexpr (kModel == CameraModelId::kOpenCVFisheye ||
                       kModel == CameraModelId::kSimpleRadialFisheye ||
                       kModel == CameraModelId::kRadialFisheye) {
    const T r = sqrt(u2 + v2);
    if (r <= T(std::numeric_limits<double>::epsilon())) {
      *du = T(0);
      *dv = T(0);
      return;
    }
    const T theta = atan(r);
    const T t2 = theta * theta;
    const T t4 = t2 * t2;
    T poly = T(1.0);
    if constexpr (kModel == CameraModelId::kSimpleRadialFisheye) {
      poly += k[0] * t2;
    } else if constexpr (kModel == CameraModelId::kRadialFisheye) {
      poly += k[0] * t2 + k[1] * t4;
    } else {
      poly += k[0] * t2 + k[1] * t4 + k[2] * t4 * t2 + k[3] * t4 * t4;
    }
    const T thetad = theta * poly;
    *du = u * thetad / r - u;
    *dv = v * thetad / r - v;
  } else if constexpr (kModel == CameraModelId::kThinPrismFisheye) {
    const T k1 = k[0], k2 = k[1], p1 = k[2], p2 = k[3];
    const T k3 = k[4], k4 = k[5], sx1 = k[6], sy1 = k[7];
    const T uv = u * v;
    const T r2 = u2 + v2;
    const T r4 = r2 * r2;
    const T r6 = r4 * r2;
    const T r8 = r6 * r2;
    const T radial = k1 * r2 + k2 * r4 + k3 * r6 + k4 * r8;
    *du = u * radial + T(2.0) * p1 * uv + p2 * (r2 + T(2.0) * u2) + sx1 * r2;
    *dv = v * radial + T(2.0) * p2 * uv + p1 * (r2 + T(2.0) * v2) + sy1 * r2;
  } else {
    *du = T(0);
    *dv = T(0);
  }
}

// Point in the camera frame -> pixel; the caller ensures p[2] > 0. For the
// models with a non-zero NumParams.
template <CameraModelId kModel, typename T>
void Project(const T* params, const T* p, T* xy) {
  static_assert(NumParams(kModel) > 0, "Project: not an additive-distortion model");
  const T u = p[0] / p[2];
  const T v = p[1] / p[2];
  T du = T(0), dv = T(0);
  Distortion<kModel>(params + ExtraOffset(kModel), u, v, &du, &dv);
  constexpr int c = PrincipalPointIndex(kModel);
  const T fx = params[0];
  const T fy = HasSingleFocal(kModel) ? params[0] : params[1];
  xy[0] = fx * (u + du) + params[c];
  xy[1] = fy * (v + dv) + params[c + 1];
}

}  // namespace locforge::camera_model

#endif  // LOCFORGE_CAMERA_MODEL_H_

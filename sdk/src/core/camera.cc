// Camera models, following COLMAP 3.8's src/base/camera_models.h: the lens
// distortion acts on the normalised image plane (u, v) = (X/Z, Y/Z), and the
// pixel is (fx * u_d + cx, fy * v_d + cy); the distortion formulas are the
// templates of camera_model.h, shared with the bundle adjuster. Models
// without a closed-form inverse are undistorted by COLMAP's Newton iteration
// with a numeric (central difference) Jacobian.
#include "locforge/camera.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "locforge/camera_model.h"
#include "locforge/error.h"
#include "locforge/params.h"

namespace locforge {

namespace {

using Id = CameraModelId;

constexpr double kEps = std::numeric_limits<double>::epsilon();

const std::vector<CameraModelInfo>& ModelTable() {
  static const std::vector<CameraModelInfo> table = {
      {Id::kSimplePinhole, "SIMPLE_PINHOLE", 3, "f, cx, cy"},
      {Id::kPinhole, "PINHOLE", 4, "fx, fy, cx, cy"},
      {Id::kSimpleRadial, "SIMPLE_RADIAL", 4, "f, cx, cy, k"},
      {Id::kRadial, "RADIAL", 5, "f, cx, cy, k1, k2"},
      {Id::kOpenCV, "OPENCV", 8, "fx, fy, cx, cy, k1, k2, p1, p2"},
      {Id::kOpenCVFisheye, "OPENCV_FISHEYE", 8, "fx, fy, cx, cy, k1, k2, k3, k4"},
      {Id::kFullOpenCV, "FULL_OPENCV", 12, "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6"},
      {Id::kFOV, "FOV", 5, "fx, fy, cx, cy, omega"},
      {Id::kSimpleRadialFisheye, "SIMPLE_RADIAL_FISHEYE", 4, "f, cx, cy, k"},
      {Id::kRadialFisheye, "RADIAL_FISHEYE", 5, "f, cx, cy, k1, k2"},
      {Id::kThinPrismFisheye, "THIN_PRISM_FISHEYE", 12,
       "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1"},
      {Id::kUnknown, "UNKNOWN_CAMERA", -1, "(any)"},
  };
  return table;
}

using camera_model::ExtraOffset;
using camera_model::HasSingleFocal;

// The distortion delta of model `id` (camera_model.h).
void Distortion(Id id, const double* k, double u, double v, double* du, double* dv) {
  switch (id) {
    case Id::kSimpleRadial: return camera_model::Distortion<Id::kSimpleRadial>(k, u, v, du, dv);
    case Id::kRadial: return camera_model::Distortion<Id::kRadial>(k, u, v, du, dv);
    case Id::kOpenCV: return camera_model::Distortion<Id::kOpenCV>(k, u, v, du, dv);
    case Id::kFullOpenCV: return camera_model::Distortion<Id::kFullOpenCV>(k, u, v, du, dv);
    case Id::kOpenCVFisheye: return camera_model::Distortion<Id::kOpenCVFisheye>(k, u, v, du, dv);
    case Id::kSimpleRadialFisheye:
      return camera_model::Distortion<Id::kSimpleRadialFisheye>(k, u, v, du, dv);
    case Id::kRadialFisheye: return camera_model::Distortion<Id::kRadialFisheye>(k, u, v, du, dv);
    case Id::kThinPrismFisheye:
      return camera_model::Distortion<Id::kThinPrismFisheye>(k, u, v, du, dv);
    default:
      *du = 0;
      *dv = 0;
      return;
  }
}

// COLMAP's BaseCameraModel::IterativeUndistortion: solves x + d(x) = x0 by
// Newton's method with a central-difference Jacobian. COLMAP stops on a
// squared step below 1e-10; we go on until the step itself is below 1e-10
// (Newton converges quadratically, so this costs one or two more iterations)
// so that round trips hold to well below a micro-pixel.
Eigen::Vector2d IterativeUndistortion(Id id, const double* k, const Eigen::Vector2d& x0) {
  constexpr int kNumIterations = 100;
  constexpr double kMaxStepNorm = 1e-10;
  constexpr double kRelStepSize = 1e-6;
  Eigen::Vector2d x = x0;
  Eigen::Vector2d dx, dx_0b, dx_0f, dx_1b, dx_1f;
  Eigen::Matrix2d J;
  for (int i = 0; i < kNumIterations; ++i) {
    const double step0 = std::max(kEps, std::abs(kRelStepSize * x(0)));
    const double step1 = std::max(kEps, std::abs(kRelStepSize * x(1)));
    Distortion(id, k, x(0), x(1), &dx(0), &dx(1));
    Distortion(id, k, x(0) - step0, x(1), &dx_0b(0), &dx_0b(1));
    Distortion(id, k, x(0) + step0, x(1), &dx_0f(0), &dx_0f(1));
    Distortion(id, k, x(0), x(1) - step1, &dx_1b(0), &dx_1b(1));
    Distortion(id, k, x(0), x(1) + step1, &dx_1f(0), &dx_1f(1));
    J(0, 0) = 1.0 + (dx_0f(0) - dx_0b(0)) / (2.0 * step0);
    J(0, 1) = (dx_1f(0) - dx_1b(0)) / (2.0 * step1);
    J(1, 0) = (dx_0f(1) - dx_0b(1)) / (2.0 * step0);
    J(1, 1) = 1.0 + (dx_1f(1) - dx_1b(1)) / (2.0 * step1);
    const Eigen::Vector2d step_x = J.inverse() * (x + dx - x0);
    if (!step_x.allFinite()) break;
    x -= step_x;
    if (step_x.norm() < kMaxStepNorm) break;
  }
  return x;
}

// FOV model (Devernay and Faugeras). COLMAP's small-omega and small-radius
// branches are second-order Taylor series of the closed forms, chosen below
// 1e-4 to avoid 0/0.
constexpr double kFovEpsilon = 1e-4;

// Distorted = undistorted * atan(2 r tan(omega/2)) / (r omega).
double FovDistortionFactor(double omega, double radius2) {
  const double omega2 = omega * omega;
  if (omega2 < kFovEpsilon) {
    // taylor(factor, omega, order 3) = 1 + omega^2/12 - r^2 omega^2/3.
    // COLMAP 3.8's Distortion reuses the undistortion's series here
    // (1 - omega^2/12 + r^2 omega^2/3), which breaks the Distort/Undistort
    // round trip by up to 1e-4 r^2; we use the correct expansion.
    return 1.0 + omega2 / 12.0 - omega2 * radius2 / 3.0;
  }
  if (radius2 < kFovEpsilon) {
    const double tan_half_omega = std::tan(omega / 2.0);
    return (-2.0 * tan_half_omega * (4.0 * radius2 * tan_half_omega * tan_half_omega - 3.0)) /
           (3.0 * omega);
  }
  const double radius = std::sqrt(radius2);
  return std::atan(radius * 2.0 * std::tan(omega / 2.0)) / (radius * omega);
}

// Undistorted = distorted * tan(r omega) / (2 r tan(omega/2)).
double FovUndistortionFactor(double omega, double radius2) {
  const double omega2 = omega * omega;
  if (omega2 < kFovEpsilon) {
    return omega2 * radius2 / 3.0 - omega2 / 12.0 + 1.0;
  }
  if (radius2 < kFovEpsilon) {
    return (omega * (omega * omega * radius2 + 3.0)) / (6.0 * std::tan(omega / 2.0));
  }
  const double radius = std::sqrt(radius2);
  return std::tan(radius * omega) / (radius * 2.0 * std::tan(omega / 2.0));
}

}  // namespace

const std::vector<CameraModelInfo>& CameraModels() { return ModelTable(); }

const CameraModelInfo* FindCameraModel(const std::string& name) {
  for (const auto& m : ModelTable())
    if (name == m.name) return &m;
  return nullptr;
}

const CameraModelInfo& CameraModelInfoOf(CameraModelId id) {
  for (const auto& m : ModelTable())
    if (m.id == id) return m;
  throw Error("unknown camera model id " + std::to_string(static_cast<int>(id)));
}

Camera Camera::FromModelName(const std::string& model_name, int width, int height,
                             std::vector<double> params) {
  const CameraModelInfo* info = FindCameraModel(model_name);
  if (!info) {
    std::vector<std::string> names;
    for (const auto& m : ModelTable()) names.push_back(m.name);
    const std::string hint = DidYouMean(model_name, names);
    throw InputError("unknown camera model '" + model_name + "'" +
                     (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
  }
  Camera camera;
  camera.model = info->id;
  camera.width = width;
  camera.height = height;
  camera.params = std::move(params);
  return camera;
}

std::string Camera::Validate() const {
  const CameraModelInfo* info = nullptr;
  for (const auto& m : ModelTable())
    if (m.id == model) info = &m;
  if (!info) return "unknown camera model id " + std::to_string(static_cast<int>(model));
  if (width < 0 || height < 0)
    return "image size " + std::to_string(width) + "x" + std::to_string(height) +
           " is negative";
  if (info->num_params < 0) return "";  // UNKNOWN_CAMERA keeps anything verbatim
  if (static_cast<int>(params.size()) != info->num_params)
    return std::string(info->name) + " takes " + std::to_string(info->num_params) +
           " parameters (" + info->param_names + "), got " + std::to_string(params.size());
  for (size_t i = 0; i < params.size(); ++i)
    if (!std::isfinite(params[i]))
      return std::string(info->name) + ": parameter " + std::to_string(i) + " is not finite";
  const int num_focals = HasSingleFocal(model) ? 1 : 2;
  for (int i = 0; i < num_focals; ++i)
    if (!(params[i] > 0))
      return std::string(info->name) + ": focal length " + FormatDouble(params[i]) +
             " is not positive";
  return "";
}

namespace {

// Throws when the camera cannot be used for geometry (UNKNOWN_CAMERA, wrong
// parameter count): reading params[] out of bounds is never an option.
void RequireUsable(const Camera& c) {
  if (c.model == Id::kUnknown)
    throw Error("camera model UNKNOWN_CAMERA has no known geometry");
  const CameraModelInfo& info = CameraModelInfoOf(c.model);
  if (static_cast<int>(c.params.size()) != info.num_params)
    throw Error(std::string(info.name) + " takes " + std::to_string(info.num_params) +
                " parameters (" + info.param_names + "), got " +
                std::to_string(c.params.size()));
}

struct Focals {
  double fx, fy, cx, cy;
};

Focals FocalsOf(const Camera& c) {
  RequireUsable(c);
  const double* p = c.params.data();
  if (HasSingleFocal(c.model)) return {p[0], p[0], p[1], p[2]};
  return {p[0], p[1], p[2], p[3]};
}

}  // namespace

double Camera::fx() const { return FocalsOf(*this).fx; }
double Camera::fy() const { return FocalsOf(*this).fy; }
double Camera::cx() const { return FocalsOf(*this).cx; }
double Camera::cy() const { return FocalsOf(*this).cy; }

Eigen::Vector2d Camera::Distort(const Eigen::Vector2d& p) const {
  RequireUsable(*this);
  const double* k = params.data() + ExtraOffset(model);
  switch (model) {
    case Id::kSimplePinhole:
    case Id::kPinhole:
      return p;
    case Id::kFOV:
      return p * FovDistortionFactor(k[0], p.squaredNorm());
    case Id::kThinPrismFisheye: {
      // Equidistant projection first (radius theta = atan(r)), then the
      // polynomial distortion on it, as COLMAP's WorldToImage does.
      const double r = p.norm();
      const Eigen::Vector2d e = r > kEps ? Eigen::Vector2d(p * (std::atan(r) / r)) : p;
      Eigen::Vector2d d;
      Distortion(model, k, e.x(), e.y(), &d.x(), &d.y());
      return e + d;
    }
    default: {
      Eigen::Vector2d d;
      Distortion(model, k, p.x(), p.y(), &d.x(), &d.y());
      return p + d;
    }
  }
}

Eigen::Vector2d Camera::Undistort(const Eigen::Vector2d& p) const {
  RequireUsable(*this);
  const double* k = params.data() + ExtraOffset(model);
  switch (model) {
    case Id::kSimplePinhole:
    case Id::kPinhole:
      return p;
    case Id::kFOV:
      return p * FovUndistortionFactor(k[0], p.squaredNorm());
    case Id::kThinPrismFisheye: {
      Eigen::Vector2d e = IterativeUndistortion(model, k, p);
      // Back from the equidistant radius theta to tan(theta).
      const double theta = e.norm();
      const double theta_cos_theta = theta * std::cos(theta);
      if (theta_cos_theta > kEps) e *= std::sin(theta) / theta_cos_theta;
      return e;
    }
    default:
      return IterativeUndistortion(model, k, p);
  }
}

Eigen::Vector2d Camera::Project(const Eigen::Vector3d& p_camera) const {
  const Focals f = FocalsOf(*this);
  const Eigen::Vector2d d = Distort(p_camera.head<2>() / p_camera.z());
  return Eigen::Vector2d(f.fx * d.x() + f.cx, f.fy * d.y() + f.cy);
}

Eigen::Vector3d Camera::Unproject(const Eigen::Vector2d& pixel) const {
  const Focals f = FocalsOf(*this);
  const Eigen::Vector2d d((pixel.x() - f.cx) / f.fx, (pixel.y() - f.cy) / f.fy);
  const Eigen::Vector2d u = Undistort(d);
  return Eigen::Vector3d(u.x(), u.y(), 1.0);
}

}  // namespace locforge

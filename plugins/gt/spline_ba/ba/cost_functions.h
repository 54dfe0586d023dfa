// Residuals of the spline bundle adjustment (paper section 3.2), as Ceres
// autodiff functors. Parameter blocks:
//   image pose T_world_camera [qx qy qz qw tx ty tz] (quaternion x R^3): one
//     6-DoF block, so the reduced camera system has one cell per image pair
//     instead of four (issue 40: fewer cell look-ups and locks per point)
//   point [3], intrinsics [camera_model::NumParams(model)] (COLMAP order)
//   control pose [qx qy qz qw tx ty tz] (see spline.h)
//   extrinsic rotation q_body_camera [qx qy qz qw]; its translation is a constant.
#ifndef LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_COST_FUNCTIONS_H_
#define LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_COST_FUNCTIONS_H_

#include <ceres/autodiff_cost_function.h>
#include <ceres/cost_function.h>

#include <Eigen/Core>

#include "locforge/camera_model.h"
#include "spline.h"

namespace locforge::sfm {

// Reprojection error (pixels): Project(K, R_wc^T (X - t_wc)) - x_observed.
template <CameraModelId kModel>
struct ReprojectionError {
  explicit ReprojectionError(const Eigen::Vector2d& xy) : observed(xy) {}

  template <typename T>
  bool operator()(const T* pose_wc, const T* point, const T* intrinsics, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(pose_wc);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(pose_wc + 4);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> X(point);
    const Eigen::Matrix<T, 3, 1> p = q.conjugate() * (X - t);
    if (p(2) <= T(0)) return false;  // behind the camera: reject the step
    T xy[2];
    camera_model::Project<kModel>(intrinsics, p.data(), xy);
    residual[0] = xy[0] - T(observed(0));
    residual[1] = xy[1] - T(observed(1));
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector2d& xy) {
    return new ceres::AutoDiffCostFunction<ReprojectionError, 2, 7, 3, camera_model::NumParams(kModel)>(
        new ReprojectionError(xy));
  }
  Eigen::Vector2d observed;
};

// The models the bundle adjuster supports.
inline bool IsSupportedModel(CameraModelId id) {
  return id == CameraModelId::kSimplePinhole || id == CameraModelId::kPinhole ||
         id == CameraModelId::kSimpleRadial || id == CameraModelId::kRadial ||
         id == CameraModelId::kOpenCV;
}
using camera_model::PrincipalPointIndex;

// Dispatch on the runtime model; nullptr for unsupported models.
inline ceres::CostFunction* CreateReprojectionError(CameraModelId model, const Eigen::Vector2d& xy) {
  switch (model) {
    case CameraModelId::kSimplePinhole:
      return ReprojectionError<CameraModelId::kSimplePinhole>::Create(xy);
    case CameraModelId::kPinhole: return ReprojectionError<CameraModelId::kPinhole>::Create(xy);
    case CameraModelId::kSimpleRadial:
      return ReprojectionError<CameraModelId::kSimpleRadial>::Create(xy);
    case CameraModelId::kRadial: return ReprojectionError<CameraModelId::kRadial>::Create(xy);
    case CameraModelId::kOpenCV: return ReprojectionError<CameraModelId::kOpenCV>::Create(xy);
    default: return nullptr;
  }
}

// Spline pose error of an image (section 3.2):
//   e_i = sqrt_info * Log( T_wc_i^-1 * T_wb(t_i + d_s) * T_bc ),
// T_wb from the 4 control poses of t_i's segment at fraction
// u = u_i + d_s / dt, where u_i is the fraction of t_i and d_s the time
// offset of the image's sensor (a 1-parameter block, constant unless
// estimated), T_bc = (q_bc parameter, t_bc constant).
// sqrt_info = diag(1/sigma_r x3, 1/sigma_t x3).
struct SplinePoseError {
  SplinePoseError(double u, double dt, const Eigen::Vector3d& t_bc, const Eigen::Matrix<double, 6, 1>& sqrt_info)
      : u(u), dt(dt), t_bc(t_bc), sqrt_info(sqrt_info) {}

  template <typename T>
  bool operator()(const T* c0, const T* c1, const T* c2, const T* c3, const T* pose_wc, const T* q_bc,
                  const T* time_offset, T* residual) const {
    const T u_offset = T(u) + time_offset[0] / T(dt);
    const PoseT<T> T_wb = EvaluateSegment(c0, c1, c2, c3, u_offset);
    PoseT<T> T_bc;
    T_bc.q = Eigen::Map<const Eigen::Quaternion<T>>(q_bc);
    T_bc.t = t_bc.cast<T>();
    const PoseT<T> T_wc = PoseT<T>::FromArray(pose_wc);
    const Eigen::Matrix<T, 6, 1> e = LogSE3T(T_wc.Inverse() * T_wb * T_bc);
    for (int k = 0; k < 6; ++k) residual[k] = T(sqrt_info(k)) * e(k);
    return true;
  }

  static ceres::CostFunction* Create(double u, double dt, const Eigen::Vector3d& t_bc,
                                     const Eigen::Matrix<double, 6, 1>& sqrt_info) {
    return new ceres::AutoDiffCostFunction<SplinePoseError, 6, 7, 7, 7, 7, 7, 4, 1>(
        new SplinePoseError(u, dt, t_bc, sqrt_info));
  }
  double u, dt;
  Eigen::Vector3d t_bc;
  Eigen::Matrix<double, 6, 1> sqrt_info;
};

// The residual of both sample errors below: sqrt_info * Log( world_to_measured
// * T_wb(t) ), T_wb from the segment's 4 control poses at fraction u.
template <typename T>
bool SplineSampleResidual(const PoseT<T>& world_to_measured, double u, const Eigen::Matrix<double, 6, 1>& sqrt_info,
                          const T* c0, const T* c1, const T* c2, const T* c3, T* residual) {
  const Eigen::Matrix<T, 6, 1> e = LogSE3T(world_to_measured * EvaluateSegment(c0, c1, c2, c3, u));
  for (int k = 0; k < 6; ++k) residual[k] = T(sqrt_info(k)) * e(k);
  return true;
}

// Spline vs a measured body pose (fitting, and the LiDAR trajectory prior):
//   e = sqrt_info * Log( T_measured^-1 * T_wb(t) ),
// or, for a trajectory that may move rigidly as a whole
// (SplineBAOptions::align_trajectories), after its alignment G (a
// control-pose-like block, world-from-LiDAR-world; CreateAligned):
//   e = sqrt_info * Log( (G * T_measured)^-1 * T_wb(t) ).
struct SplineSampleError {
  SplineSampleError(double u, const Pose& measured, const Eigen::Matrix<double, 6, 1>& sqrt_info)
      : u(u), measured_inverse(measured.Inverse()), sqrt_info(sqrt_info) {}

  template <typename T>
  bool operator()(const T* c0, const T* c1, const T* c2, const T* c3, T* residual) const {
    return SplineSampleResidual(PoseT<T>::Cast(measured_inverse), u, sqrt_info, c0, c1, c2, c3, residual);
  }
  template <typename T>
  bool operator()(const T* c0, const T* c1, const T* c2, const T* c3, const T* g, T* residual) const {
    return SplineSampleResidual(PoseT<T>::Cast(measured_inverse) * PoseT<T>::FromArray(g).Inverse(), u, sqrt_info,
                                c0, c1, c2, c3, residual);
  }

  static ceres::CostFunction* Create(double u, const Pose& measured,
                                     const Eigen::Matrix<double, 6, 1>& sqrt_info) {
    return new ceres::AutoDiffCostFunction<SplineSampleError, 6, 7, 7, 7, 7>(
        new SplineSampleError(u, measured, sqrt_info));
  }
  static ceres::CostFunction* CreateAligned(double u, const Pose& measured,
                                            const Eigen::Matrix<double, 6, 1>& sqrt_info) {
    return new ceres::AutoDiffCostFunction<SplineSampleError, 6, 7, 7, 7, 7, 7>(
        new SplineSampleError(u, measured, sqrt_info));
  }
  double u;
  Pose measured_inverse;
  Eigen::Matrix<double, 6, 1> sqrt_info;
};

// The LiDAR prior of a trajectory whose samples may be scaled
// (SplineBAOptions::scale_trajectories): the sample's translation times
// exp(s) (s: a 1-parameter block, the trajectory's log-scale), then as
// SplineSampleError, without or with the alignment G (CreateAligned):
//   e = sqrt_info * Log( (G * S_s(T_measured))^-1 * T_wb(t) ),  S_s(R, p) = (R, exp(s) p).
struct ScaledSplineSampleError {
  ScaledSplineSampleError(double u, const Pose& measured, const Eigen::Matrix<double, 6, 1>& sqrt_info)
      : u(u), measured(measured), sqrt_info(sqrt_info) {}

  template <typename T>
  bool operator()(const T* c0, const T* c1, const T* c2, const T* c3, const T* log_scale, T* residual) const {
    return SplineSampleResidual(Scaled(log_scale).Inverse(), u, sqrt_info, c0, c1, c2, c3, residual);
  }
  template <typename T>
  bool operator()(const T* c0, const T* c1, const T* c2, const T* c3, const T* g, const T* log_scale,
                  T* residual) const {
    return SplineSampleResidual((PoseT<T>::FromArray(g) * Scaled(log_scale)).Inverse(), u, sqrt_info, c0, c1, c2,
                                c3, residual);
  }

  static ceres::CostFunction* Create(double u, const Pose& measured, const Eigen::Matrix<double, 6, 1>& sqrt_info) {
    return new ceres::AutoDiffCostFunction<ScaledSplineSampleError, 6, 7, 7, 7, 7, 1>(
        new ScaledSplineSampleError(u, measured, sqrt_info));
  }
  static ceres::CostFunction* CreateAligned(double u, const Pose& measured,
                                            const Eigen::Matrix<double, 6, 1>& sqrt_info) {
    return new ceres::AutoDiffCostFunction<ScaledSplineSampleError, 6, 7, 7, 7, 7, 7, 1>(
        new ScaledSplineSampleError(u, measured, sqrt_info));
  }
  double u;
  Pose measured;
  Eigen::Matrix<double, 6, 1> sqrt_info;

 private:
  template <typename T>
  PoseT<T> Scaled(const T* log_scale) const {
    PoseT<T> M = PoseT<T>::Cast(measured);
    M.t *= exp(log_scale[0]);
    return M;
  }
};

// Wheeled-base kinematics (SplineBAOptions::nonholonomic_sigma_mps): the
// body does not slip sideways. Its velocity in the middle of a segment, from
// the chord T_wb(1/4) -> T_wb(3/4) seen in the body frame at 1/2, has no
// lateral part:
//   v = R_wb(1/2)^T (p(3/4) - p(1/4)) / (dt / 2),  e = v_y / sigma.
// On an arc of constant curvature the chord is parallel to the velocity at
// its middle, so a base driving arcs leaves e = 0 exactly. (Vertical motion
// is left free: floors are not flat to a millimetre, bases pitch.)
struct NonholonomicError {
  NonholonomicError(double dt_s, double sigma_mps) : dt_s(dt_s), sigma_mps(sigma_mps) {}
  template <typename T>
  bool operator()(const T* c0, const T* c1, const T* c2, const T* c3, T* residual) const {
    const PoseT<T> before = EvaluateSegment(c0, c1, c2, c3, 0.25);
    const PoseT<T> middle = EvaluateSegment(c0, c1, c2, c3, 0.5);
    const PoseT<T> after = EvaluateSegment(c0, c1, c2, c3, 0.75);
    const Eigen::Matrix<T, 3, 1> v = middle.q.conjugate() * (after.t - before.t) / T(0.5 * dt_s);
    residual[0] = v.y() / T(sigma_mps);
    return true;
  }
  static ceres::CostFunction* Create(double dt_s, double sigma_mps) {
    return new ceres::AutoDiffCostFunction<NonholonomicError, 1, 7, 7, 7, 7>(new NonholonomicError(dt_s, sigma_mps));
  }
  double dt_s, sigma_mps;
};

// A quadratic cost on a point: e = S (x - x0) + c (BAProblem::PointSummary).
struct PointSummaryError {
  PointSummaryError(const Eigen::Vector3d& x0, const Eigen::Matrix3d& S, const Eigen::Vector3d& c)
      : x0(x0), S(S), c(c) {}
  template <typename T>
  bool operator()(const T* x, T* residual) const {
    const Eigen::Matrix<T, 3, 1> d(x[0] - T(x0.x()), x[1] - T(x0.y()), x[2] - T(x0.z()));
    const Eigen::Matrix<T, 3, 1> e = S.cast<T>() * d + c.cast<T>();
    for (int k = 0; k < 3; ++k) residual[k] = e(k);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector3d& x0, const Eigen::Matrix3d& S, const Eigen::Vector3d& c) {
    return new ceres::AutoDiffCostFunction<PointSummaryError, 3, 3>(new PointSummaryError(x0, S, c));
  }
  Eigen::Vector3d x0;
  Eigen::Matrix3d S;
  Eigen::Vector3d c;
};

// Pull of a control pose to a fixed value (keeps segments without data
// determined): e = sqrt_info * Log( T_ref^-1 * T_control ).
struct ControlPoseError {
  ControlPoseError(const Pose& ref, const Eigen::Matrix<double, 6, 1>& sqrt_info)
      : ref_inverse(ref.Inverse()), sqrt_info(sqrt_info) {}
  template <typename T>
  bool operator()(const T* c, T* residual) const {
    const Eigen::Matrix<T, 6, 1> e = LogSE3T(PoseT<T>::Cast(ref_inverse) * PoseT<T>::FromArray(c));
    for (int k = 0; k < 6; ++k) residual[k] = T(sqrt_info(k)) * e(k);
    return true;
  }
  static ceres::CostFunction* Create(const Pose& ref, const Eigen::Matrix<double, 6, 1>& sqrt_info) {
    return new ceres::AutoDiffCostFunction<ControlPoseError, 6, 7>(new ControlPoseError(ref, sqrt_info));
  }
  Pose ref_inverse;
  Eigen::Matrix<double, 6, 1> sqrt_info;
};

// Second difference of three consecutive control poses (zero on a constant
// twist): e = sqrt_info * Log( (T_{k-1}^-1 T_k)^-1 (T_k^-1 T_{k+1}) ). A weak
// smoothness term that fixes the end control poses a fit leaves free.
struct ControlSmoothnessError {
  explicit ControlSmoothnessError(const Eigen::Matrix<double, 6, 1>& sqrt_info) : sqrt_info(sqrt_info) {}
  template <typename T>
  bool operator()(const T* c0, const T* c1, const T* c2, T* residual) const {
    const PoseT<T> P0 = PoseT<T>::FromArray(c0), P1 = PoseT<T>::FromArray(c1), P2 = PoseT<T>::FromArray(c2);
    const Eigen::Matrix<T, 6, 1> e = LogSE3T((P0.Inverse() * P1).Inverse() * (P1.Inverse() * P2));
    for (int k = 0; k < 6; ++k) residual[k] = T(sqrt_info(k)) * e(k);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Matrix<double, 6, 1>& sqrt_info) {
    return new ceres::AutoDiffCostFunction<ControlSmoothnessError, 6, 7, 7, 7>(new ControlSmoothnessError(sqrt_info));
  }
  Eigen::Matrix<double, 6, 1> sqrt_info;
};

// e = weight * sum_i x_i over 1-parameter blocks: the gauge of the clock
// offsets (their sum held at 0), of the trajectories' log-scales, and with
// one block a plain prior x / sigma. Linear, so its Jacobian is the
// constant weight.
class ScalarSumError : public ceres::CostFunction {
 public:
  ScalarSumError(int num_blocks, double weight) : weight_(weight) {
    set_num_residuals(1);
    for (int i = 0; i < num_blocks; ++i) mutable_parameter_block_sizes()->push_back(1);
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const int n = static_cast<int>(parameter_block_sizes().size());
    double sum = 0;
    for (int i = 0; i < n; ++i) sum += parameters[i][0];
    residuals[0] = weight_ * sum;
    if (jacobians)
      for (int i = 0; i < n; ++i)
        if (jacobians[i]) jacobians[i][0] = weight_;
    return true;
  }

 private:
  double weight_;
};

inline Eigen::Matrix<double, 6, 1> SqrtInformation(double sigma_rotation_rad, double sigma_translation_m) {
  Eigen::Matrix<double, 6, 1> s;
  s << Eigen::Vector3d::Constant(1.0 / sigma_rotation_rad), Eigen::Vector3d::Constant(1.0 / sigma_translation_m);
  return s;
}

}  // namespace locforge::sfm

#endif  // LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_COST_FUNCTIONS_H_

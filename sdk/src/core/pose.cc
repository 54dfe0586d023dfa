#include "locforge/pose.h"

#include <Eigen/SVD>
#include <cmath>

#include "locforge/error.h"

namespace locforge {

namespace {

// Below this rotation angle (radians) the closed forms lose precision to
// cancellation and their Taylor series (truncated past theta^4, error below
// 1e-17) are used instead.
constexpr double kSeriesAngle = 1e-2;

Eigen::Matrix3d Hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d W;
  W << 0, -w.z(), w.y(),  //
      w.z(), 0, -w.x(),   //
      -w.y(), w.x(), 0;
  return W;
}

// Left Jacobian of SO(3): V = I + a W + b W^2, with
// a = (1 - cos t) / t^2 and b = (t - sin t) / t^3.
Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& w) {
  const double t = w.norm();
  const double t2 = t * t;
  double a, b;
  if (t < kSeriesAngle) {
    a = 0.5 - t2 / 24.0 + t2 * t2 / 720.0;
    b = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0;
  } else {
    a = (1.0 - std::cos(t)) / t2;
    b = (t - std::sin(t)) / (t2 * t);
  }
  const Eigen::Matrix3d W = Hat(w);
  return Eigen::Matrix3d::Identity() + a * W + b * W * W;
}

// Inverse of the left Jacobian: I - W/2 + c W^2 with
// c = (1 - (t/2) cot(t/2)) / t^2, written with cot so that it stays finite at
// t = pi (where it equals 1/pi^2), unlike the usual (1 + cos t)/(2 t sin t) form.
Eigen::Matrix3d InverseLeftJacobianSO3(const Eigen::Vector3d& w) {
  const double t = w.norm();
  const double t2 = t * t;
  double c;
  if (t < kSeriesAngle) {
    c = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0;
  } else {
    const double half = 0.5 * t;
    c = (1.0 - half * std::cos(half) / std::sin(half)) / t2;
  }
  const Eigen::Matrix3d W = Hat(w);
  return Eigen::Matrix3d::Identity() - 0.5 * W + c * W * W;
}

}  // namespace

Pose Pose::FromMatrix(const Eigen::Matrix4d& m) {
  if (!m.allFinite()) throw Error("Pose::FromMatrix: matrix has non-finite entries");
  // Project the 3x3 block onto the nearest rotation, so matrices read from
  // text files with a few digits still give a proper rotation.
  const Eigen::Matrix3d A = m.topLeftCorner<3, 3>();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  const Eigen::Matrix3d V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0) U.col(2) *= -1.0;
  const Eigen::Matrix3d R = U * V.transpose();
  return Pose(Eigen::Quaterniond(R), m.topRightCorner<3, 1>());
}

Eigen::Matrix4d Pose::Matrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = R();
  m.topRightCorner<3, 1>() = t;
  return m;
}

Eigen::Quaterniond ExpSO3(const Eigen::Vector3d& w) {
  const double t = w.norm();
  const double t2 = t * t;
  // q = (cos(t/2), sin(t/2)/t * w); sin(t/2)/t -> 1/2 as t -> 0.
  double s;
  if (t < kSeriesAngle) {
    s = 0.5 - t2 / 48.0 + t2 * t2 / 3840.0;
  } else {
    s = std::sin(0.5 * t) / t;
  }
  Eigen::Quaterniond q(std::cos(0.5 * t), s * w.x(), s * w.y(), s * w.z());
  return q.normalized();
}

Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  // q and -q are the same rotation; w >= 0 gives the angle in [0, pi].
  if (q.w() < 0) q.coeffs() *= -1.0;
  const Eigen::Vector3d v = q.vec();
  const double n = v.norm();
  const double w = q.w();
  double factor;  // angle / n
  if (n < 1e-8) {
    // 2 atan(n / w) / n = 2/w - 2 n^2 / (3 w^3) + ...; w ~ 1 here.
    factor = 2.0 / w - 2.0 * n * n / (3.0 * w * w * w);
  } else {
    // atan2 is well conditioned near pi too (w -> 0, n -> 1).
    factor = 2.0 * std::atan2(n, w) / n;
  }
  return factor * v;
}

Pose ExpSE3(const Vector6d& xi) {
  const Eigen::Vector3d w = xi.head<3>();
  const Eigen::Vector3d v = xi.tail<3>();
  return Pose(ExpSO3(w), LeftJacobianSO3(w) * v);
}

Vector6d LogSE3(const Pose& T) {
  const Eigen::Vector3d w = LogSO3(T.q);
  Vector6d xi;
  xi.head<3>() = w;
  xi.tail<3>() = InverseLeftJacobianSO3(w) * T.t;
  return xi;
}

Pose Interpolate(const Pose& a, const Pose& b, double alpha) {
  // Eigen's slerp takes the shorter arc (it flips b when a.b < 0).
  const Eigen::Quaterniond q = a.q.slerp(alpha, b.q);
  const Eigen::Vector3d t = (1.0 - alpha) * a.t + alpha * b.t;
  return Pose(q, t);
}

double RotationAngleDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  const Eigen::Quaterniond d = a.normalized().conjugate() * b.normalized();
  // 2 atan2(|v|, |w|) is accurate at small angles, unlike 2 acos(|w|).
  const double angle = 2.0 * std::atan2(d.vec().norm(), std::abs(d.w()));
  return angle * 180.0 / M_PI;
}

}  // namespace locforge

// Uniform cumulative cubic B-spline in SE(3) (Lovegrove, Patron-Perez,
// Sibley, BMVC 2013, "Spline Fusion", eq. 4-6):
//
//   T(u) = T_{s} * prod_{j=1..3} Exp( Btilde_j(u) * Omega_{s+j} ),
//   Omega_k = Log( T_{k-1}^-1 * T_k ),  Btilde(u) = C [1 u u^2 u^3]^T,
//   C = 1/6 [6 0 0 0; 5 3 -3 1; 1 3 3 -2; 0 0 0 1]            (eq. 6)
//
// for t in segment s: [t0 + s dt, t0 + (s+1) dt), u = (t - t0)/dt - s, so
// control pose k is centred at time t0 + (k-1) dt and a spline over
// n segments has n + 3 control poses. The spline is of T_world_body
// (world-from-body); increments are right-multiplied (body frame).
//
// Parameterisation inside Ceres: a control pose is a 7-vector
// [qx, qy, qz, qw, tx, ty, tz] (Eigen's quaternion memory layout x,y,z,w,
// then the translation), with the manifold
// ProductManifold<EigenQuaternionManifold, EuclideanManifold<3>>.
// The SE(3) Exp/Log here use the tangent order (rx, ry, rz, tx, ty, tz) of
// locforge::ExpSE3/LogSE3 and are templated so Ceres Jets pass through
// (small-angle branches are Taylor series, exact derivatives at 0).
#ifndef LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_SPLINE_H_
#define LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_SPLINE_H_

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "locforge/pose.h"

namespace locforge::sfm {

// --------------------------------------------------------- templated SE(3)
template <typename T>
struct PoseT {
  Eigen::Quaternion<T> q = Eigen::Quaternion<T>::Identity();
  Eigen::Matrix<T, 3, 1> t = Eigen::Matrix<T, 3, 1>::Zero();

  // From the 7-vector [qx, qy, qz, qw, tx, ty, tz].
  static PoseT FromArray(const T* p) {
    PoseT r;
    r.q = Eigen::Quaternion<T>(p[3], p[0], p[1], p[2]);
    r.t = Eigen::Matrix<T, 3, 1>(p[4], p[5], p[6]);
    return r;
  }
  // A fixed (double) pose as a constant of the autodiff scalar type.
  static PoseT Cast(const Pose& p) {
    PoseT r;
    r.q = p.q.cast<T>();
    r.t = p.t.cast<T>();
    return r;
  }
  PoseT operator*(const PoseT& o) const {
    PoseT r;
    r.q = q * o.q;
    r.t = q * o.t + t;
    return r;
  }
  PoseT Inverse() const {
    PoseT r;
    r.q = q.conjugate();
    r.t = -(r.q * t);
    return r;
  }
  Eigen::Matrix<T, 3, 1> operator*(const Eigen::Matrix<T, 3, 1>& p) const { return q * p + t; }
};

template <typename T>
Eigen::Matrix<T, 3, 3> Hat(const Eigen::Matrix<T, 3, 1>& w) {
  Eigen::Matrix<T, 3, 3> W;
  W << T(0), -w(2), w(1), w(2), T(0), -w(0), -w(1), w(0), T(0);
  return W;
}

// Rotation vector -> unit quaternion.
template <typename T>
Eigen::Quaternion<T> ExpSO3T(const Eigen::Matrix<T, 3, 1>& w) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta2 = w.squaredNorm();
  T real, k;
  if (theta2 > T(1e-8)) {
    const T theta = sqrt(theta2);
    real = cos(theta / T(2));
    k = sin(theta / T(2)) / theta;
  } else {  // Taylor: cos(x/2) = 1 - x^2/8, sin(x/2)/x = 1/2 - x^2/48
    real = T(1) - theta2 / T(8);
    k = T(0.5) - theta2 / T(48);
  }
  return Eigen::Quaternion<T>(real, k * w(0), k * w(1), k * w(2));
}

// Unit quaternion -> rotation vector of the shorter arc (|w| <= pi).
template <typename T>
Eigen::Matrix<T, 3, 1> LogSO3T(const Eigen::Quaternion<T>& q_in) {
  using std::atan2;
  using std::sqrt;
  Eigen::Quaternion<T> q = q_in;
  if (q.w() < T(0)) q.coeffs() = -q.coeffs();
  const Eigen::Matrix<T, 3, 1> v = q.vec();
  const T n2 = v.squaredNorm();
  if (n2 > T(1e-16)) {
    const T n = sqrt(n2);
    return (T(2) * atan2(n, q.w()) / n) * v;
  }
  // 2 atan(n/w)/n = 2/w (1 - n^2/(3 w^2)) + O(n^4)
  return (T(2) / q.w() * (T(1) - n2 / (T(3) * q.w() * q.w()))) * v;
}

// Left Jacobian of SO(3), V = I + A W + B W^2, and its inverse.
template <typename T>
Eigen::Matrix<T, 3, 3> LeftJacobianSO3T(const Eigen::Matrix<T, 3, 1>& w) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta2 = w.squaredNorm();
  T a, b;
  if (theta2 > T(1e-2)) {
    const T theta = sqrt(theta2);
    a = (T(1) - cos(theta)) / theta2;
    b = (theta - sin(theta)) / (theta2 * theta);
  } else {  // Taylor series: the closed forms cancel badly (in Jets too) at small angles
    const T theta4 = theta2 * theta2;
    a = T(0.5) - theta2 / T(24) + theta4 / T(720) - theta4 * theta2 / T(40320);
    b = T(1.0 / 6.0) - theta2 / T(120) + theta4 / T(5040) - theta4 * theta2 / T(362880);
  }
  const Eigen::Matrix<T, 3, 3> W = Hat(w);
  return Eigen::Matrix<T, 3, 3>::Identity() + a * W + b * W * W;
}

template <typename T>
Eigen::Matrix<T, 3, 3> InverseLeftJacobianSO3T(const Eigen::Matrix<T, 3, 1>& w) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta2 = w.squaredNorm();
  T c;
  if (theta2 > T(1e-2)) {
    const T theta = sqrt(theta2);
    c = (T(1) - theta * sin(theta) / (T(2) * (T(1) - cos(theta)))) / theta2;
  } else {  // Taylor series (1/12 + x^2/720 + x^4/30240 + x^6/1209600)
    const T theta4 = theta2 * theta2;
    c = T(1.0 / 12.0) + theta2 / T(720) + theta4 / T(30240) + theta4 * theta2 / T(1209600);
  }
  const Eigen::Matrix<T, 3, 3> W = Hat(w);
  return Eigen::Matrix<T, 3, 3>::Identity() - T(0.5) * W + c * W * W;
}

template <typename T>
PoseT<T> ExpSE3T(const Eigen::Matrix<T, 6, 1>& xi) {
  const Eigen::Matrix<T, 3, 1> w = xi.template head<3>();
  PoseT<T> r;
  r.q = ExpSO3T(w);
  r.t = LeftJacobianSO3T(w) * Eigen::Matrix<T, 3, 1>(xi.template tail<3>());
  return r;
}

template <typename T>
Eigen::Matrix<T, 6, 1> LogSE3T(const PoseT<T>& p) {
  const Eigen::Matrix<T, 3, 1> w = LogSO3T(p.q);
  Eigen::Matrix<T, 6, 1> xi;
  xi.template head<3>() = w;
  xi.template tail<3>() = InverseLeftJacobianSO3T(w) * p.t;
  return xi;
}

// Cumulative basis Btilde(u) (eq. 6); Btilde_0 = 1 always.
template <typename U>
Eigen::Matrix<U, 4, 1> CumulativeBasis(const U& u) {
  const U u2 = u * u, u3 = u2 * u;
  return Eigen::Matrix<U, 4, 1>(U(1.0), (U(5.0) + U(3.0) * u - U(3.0) * u2 + u3) / U(6.0),
                                (U(1.0) + U(3.0) * u + U(3.0) * u2 - U(2.0) * u3) / U(6.0), u3 / U(6.0));
}

// Spline value (eq. 4) from the 4 control poses of the segment, each a
// 7-vector as above, at the segment fraction u in [0, 1] (u may be a Jet:
// time offsets are estimated through it; slightly outside [0, 1] the
// segment's polynomial extends smoothly).
template <typename T, typename U = double>
PoseT<T> EvaluateSegment(const T* c0, const T* c1, const T* c2, const T* c3, const U& u) {
  const Eigen::Matrix<U, 4, 1> b = CumulativeBasis(u);
  const PoseT<T> P[4] = {PoseT<T>::FromArray(c0), PoseT<T>::FromArray(c1),
                         PoseT<T>::FromArray(c2), PoseT<T>::FromArray(c3)};
  PoseT<T> result = P[0];
  for (int j = 1; j < 4; ++j) {
    const Eigen::Matrix<T, 6, 1> omega = LogSE3T(P[j - 1].Inverse() * P[j]);
    result = result * ExpSE3T<T>(T(b(j)) * omega);
  }
  return result;
}

// ------------------------------------------------------------------ spline
class SE3Spline {
 public:
  double t0 = 0;    // time of the start of segment 0, seconds
  double dt = 0.1;  // knot spacing, seconds
  std::vector<Pose> control;  // T_world_body control poses; size = segments + 3

  int NumSegments() const { return static_cast<int>(control.size()) - 3; }
  double EndTime() const { return t0 + NumSegments() * dt; }
  // Segment of time t and its fraction u; times outside [t0, EndTime()] are
  // clamped to the first/last segment (u in [0, 1], no extrapolation).
  void Locate(double t, int* segment, double* u) const;

  // T_world_body(t).
  Pose Evaluate(double t) const;

  // Fits a spline with the given knot spacing, covering [min(times),
  // max(times)] (optionally widened to [t_begin, t_end] to cover images),
  // to the samples T_world_body[i] at times_s[i]: control poses initialised
  // by interpolating the samples at their centre times, then a least-squares
  // fit of Log(T_sample^-1 T(t_i)) (Ceres), with a weak smoothness term on
  // the control poses' second differences (zero on constant twists) so the
  // end control poses and segments without samples stay determined. Needs >= 1 sample; times need not be sorted.
  static SE3Spline Fit(const std::vector<double>& times_s, const std::vector<Pose>& T_world_body,
                       double knot_spacing_s);
  static SE3Spline Fit(const std::vector<double>& times_s, const std::vector<Pose>& T_world_body,
                       double knot_spacing_s, double t_begin, double t_end);
};

// 7-vector [qx qy qz qw tx ty tz] <-> Pose.
void PoseToArray(const Pose& p, double* a);
Pose PoseFromArray(const double* a);

}  // namespace locforge::sfm

#endif  // LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_SPLINE_H_

// The SE(3) spline: templated Exp/Log against the SDK's, exactness on a
// constant twist, fitting sampled smooth motion, C2 continuity.
#include "spline.h"

#include <gtest/gtest.h>

#include <random>

namespace locforge::sfm {
namespace {

Vector6d RandomTwist(std::mt19937& rng, double scale) {
  std::normal_distribution<double> n(0, scale);
  Vector6d xi;
  for (int k = 0; k < 6; ++k) xi(k) = n(rng);
  return xi;
}

double PositionError(const Pose& a, const Pose& b) { return (a.t - b.t).norm(); }

TEST(Spline, TemplatedExpLogMatchTheSdk) {
  std::mt19937 rng(1);
  for (double scale : {1e-9, 1e-4, 1e-2, 0.5, 1.5}) {
    for (int i = 0; i < 20; ++i) {
      const Vector6d xi = RandomTwist(rng, scale);
      if (xi.head<3>().norm() > 3.0) continue;  // Log returns the angle in [0, pi]
      const Pose a = ExpSE3(xi);
      const PoseT<double> b = ExpSE3T<double>(xi);
      EXPECT_LT(RotationAngleDeg(a.q, b.q), 1e-10);
      EXPECT_LT((a.t - b.t).norm(), 1e-12 * (1 + xi.norm()));
      EXPECT_LT((LogSE3T(b) - xi).norm(), 1e-10 * (1 + xi.norm())) << scale;
      EXPECT_LT((LogSE3T(b) - LogSE3(a)).norm(), 1e-10 * (1 + xi.norm()));
    }
  }
}

// Control poses on a one-parameter subgroup, T_k = A Exp(k xi): every
// Omega equals xi and Btilde_1 + Btilde_2 + Btilde_3 = 1 + u, so the spline
// is exactly the constant-twist motion A Exp(((t - t0)/dt + 1) xi).
TEST(Spline, ConstantTwistIsReproducedExactly) {
  std::mt19937 rng(2);
  const Pose A = ExpSE3(RandomTwist(rng, 1.0));
  Vector6d xi;
  xi << 0.02, -0.01, 0.05, 0.3, 0.1, -0.02;  // per knot
  SE3Spline spline;
  spline.t0 = 3.0;
  spline.dt = 0.2;
  for (int k = 0; k < 13; ++k) spline.control.push_back(A * ExpSE3(static_cast<double>(k) * xi));
  for (double t = spline.t0; t <= spline.EndTime(); t += 0.0137) {
    const Pose expected = A * ExpSE3(((t - spline.t0) / spline.dt + 1.0) * xi);
    const Pose got = spline.Evaluate(t);
    EXPECT_LT(PositionError(got, expected), 1e-12) << t;
    EXPECT_LT(RotationAngleDeg(got.q, expected.q), 1e-10) << t;
  }
}

// A smooth platform-like motion sampled at 10 Hz (as the LiDAR trajectory).
Pose SmoothMotion(double t) {
  const double th = 0.1 * t;
  const Eigen::Vector3d p(10 * std::cos(th), 6 * std::sin(th), 0.05 * std::sin(1.5 * t));
  const double yaw = std::atan2(6 * std::cos(th), -10 * std::sin(th));
  const Eigen::Quaterniond q = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(0.02 * std::sin(0.9 * t), Eigen::Vector3d::UnitX());
  return Pose(q, p);
}

TEST(Spline, FitReproducesSampledSmoothMotion) {
  std::vector<double> times;
  std::vector<Pose> poses;
  for (double t = 0; t <= 20.0 + 1e-9; t += 0.1) {
    times.push_back(t);
    poses.push_back(SmoothMotion(t));
  }
  for (double dt : {0.1, 0.25}) {
    const SE3Spline spline = SE3Spline::Fit(times, poses, dt);
    ASSERT_GE(spline.EndTime(), 20.0 - 1e-9);
    double max_p = 0, max_r = 0;
    for (double t = 0.05; t < 20.0; t += 0.0731) {  // between samples too
      const Pose got = spline.Evaluate(t), expected = SmoothMotion(t);
      max_p = std::max(max_p, PositionError(got, expected));
      max_r = std::max(max_r, RotationAngleDeg(got.q, expected.q));
    }
    // Velocity ~1 m/s, accelerations ~0.1 m/s^2: interpolation error is
    // well under a millimetre at these knot spacings.
    EXPECT_LT(max_p, 1e-3) << dt;
    EXPECT_LT(max_r, 0.01) << dt;
  }
}

TEST(Spline, FitOfConstantTwistSamplesIsExact) {
  Vector6d xi;
  xi << 0.05, 0.02, -0.1, 1.0, 0.2, 0.0;  // per second
  std::vector<double> times;
  std::vector<Pose> poses;
  for (double t = 0; t <= 5.0 + 1e-9; t += 0.1) {
    times.push_back(t);
    poses.push_back(ExpSE3(t * xi));
  }
  const SE3Spline spline = SE3Spline::Fit(times, poses, 0.3);
  for (double t = 0; t <= 5.0; t += 0.05) {
    EXPECT_LT(PositionError(spline.Evaluate(t), ExpSE3(t * xi)), 1e-6) << t;
    EXPECT_LT(RotationAngleDeg(spline.Evaluate(t).q, ExpSE3(t * xi).q), 1e-5) << t;
  }
}

// C2: velocity and acceleration (central differences) are continuous across
// knots: their jump over [t_k - e, t_k + e] shrinks linearly with e.
TEST(Spline, IsTwiceContinuouslyDifferentiableAcrossKnots) {
  std::mt19937 rng(3);
  SE3Spline spline;
  spline.t0 = 0;
  spline.dt = 0.5;
  Pose T;
  for (int k = 0; k < 10; ++k) {
    T = T * ExpSE3(RandomTwist(rng, 0.3));  // random, wiggly control poses
    spline.control.push_back(T);
  }
  const double h = 1e-4;
  auto acc = [&](double t) {
    return Eigen::Vector3d((spline.Evaluate(t + h).t - 2 * spline.Evaluate(t).t + spline.Evaluate(t - h).t) / (h * h));
  };
  auto rot_vel = [&](double t) {
    return Eigen::Vector3d(LogSO3(spline.Evaluate(t - h).q.conjugate() * spline.Evaluate(t + h).q) / (2 * h));
  };
  for (int k = 1; k < spline.NumSegments(); ++k) {
    const double tk = spline.t0 + k * spline.dt;
    const double jump_a_far = (acc(tk + 1e-2) - acc(tk - 1e-2)).norm();
    const double jump_a_near = (acc(tk + 1e-3) - acc(tk - 1e-3)).norm();
    EXPECT_LT(jump_a_near, 0.2 * jump_a_far + 1e-3) << k;  // ~0.1: linear in e, no step
    EXPECT_LT((rot_vel(tk + 1e-3) - rot_vel(tk - 1e-3)).norm(), 0.2 * (rot_vel(tk + 1e-2) - rot_vel(tk - 1e-2)).norm() + 1e-4);
  }
}

}  // namespace
}  // namespace locforge::sfm

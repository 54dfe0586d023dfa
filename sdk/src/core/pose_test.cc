#include "locforge/pose.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <unsupported/Eigen/MatrixFunctions>

#include "locforge/error.h"

namespace locforge {
namespace {

// The 4x4 twist matrix [hat(w) v; 0 0] of xi = (w, v): its matrix exponential
// (Eigen's Pade approximation, independent of pose.cc) is the SE(3) exp.
Eigen::Matrix4d TwistMatrix(const Vector6d& xi) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Zero();
  m(0, 1) = -xi(2);
  m(0, 2) = xi(1);
  m(1, 0) = xi(2);
  m(1, 2) = -xi(0);
  m(2, 0) = -xi(1);
  m(2, 1) = xi(0);
  m.topRightCorner<3, 1>() = xi.tail<3>();
  return m;
}

Vector6d Twist(const Eigen::Vector3d& w, const Eigen::Vector3d& v) {
  Vector6d xi;
  xi << w, v;
  return xi;
}

double PoseDistance(const Pose& a, const Pose& b) {
  return (a.Matrix() - b.Matrix()).cwiseAbs().maxCoeff();
}

class PoseRandom : public ::testing::Test {
 protected:
  std::mt19937 rng{42};
  Eigen::Vector3d RandomUnit() {
    std::normal_distribution<double> n;
    return Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
  }
  double Uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }
  Pose RandomPose() {
    return ExpSE3(Twist(RandomUnit() * Uniform(0, 3.1), RandomUnit() * Uniform(0, 10)));
  }
};

TEST_F(PoseRandom, ExpMatchesMatrixExponential) {
  for (int i = 0; i < 200; ++i) {
    const Vector6d xi = Twist(RandomUnit() * Uniform(0, 3.1), RandomUnit() * Uniform(0, 5));
    const Eigen::Matrix4d expected = TwistMatrix(xi).exp();
    EXPECT_LT((ExpSE3(xi).Matrix() - expected).cwiseAbs().maxCoeff(), 1e-12) << xi.transpose();
  }
}

TEST(Pose, ExpKnownScrewMotion) {
  // Rotating by pi/2 about z while moving at unit speed along x ends at
  // integral_0^1 Rz(pi/2 s) (1,0,0) ds = (2/pi, 2/pi, 0).
  const Pose T = ExpSE3(Twist({0, 0, M_PI / 2}, {1, 0, 0}));
  EXPECT_NEAR(T.t.x(), 2 / M_PI, 1e-15);
  EXPECT_NEAR(T.t.y(), 2 / M_PI, 1e-15);
  EXPECT_NEAR(T.t.z(), 0, 1e-15);
  EXPECT_NEAR((T * Eigen::Vector3d(1, 0, 0) - T.t - Eigen::Vector3d(0, 1, 0)).norm(), 0, 1e-15);
  // Pure translation: the tangent is the translation.
  const Pose P = ExpSE3(Twist({0, 0, 0}, {1, -2, 3}));
  EXPECT_EQ(P.t, Eigen::Vector3d(1, -2, 3));
  EXPECT_NEAR(P.q.angularDistance(Eigen::Quaterniond::Identity()), 0, 1e-16);
}

TEST_F(PoseRandom, LogOfExpIsIdentityBelowPi) {
  for (int i = 0; i < 500; ++i) {
    const Vector6d xi = Twist(RandomUnit() * Uniform(0, 3.1), RandomUnit() * Uniform(0, 10));
    EXPECT_LT((LogSE3(ExpSE3(xi)) - xi).norm(), 1e-11) << xi.transpose();
  }
}

TEST_F(PoseRandom, ExpOfLogIsIdentity) {
  for (int i = 0; i < 500; ++i) {
    const Pose T = RandomPose();
    EXPECT_LT(PoseDistance(ExpSE3(LogSE3(T)), T), 1e-12);
  }
}

TEST_F(PoseRandom, RoundTripNearIdentity) {
  // Angles on both sides of the switch between series and closed forms.
  for (double angle : {0.0, 1e-15, 1e-12, 1e-9, 1e-6, 1e-4, 9.99e-3, 1e-2, 1.001e-2, 0.1}) {
    for (int i = 0; i < 20; ++i) {
      const Vector6d xi = Twist(RandomUnit() * angle, RandomUnit() * Uniform(0, 10));
      const Pose T = ExpSE3(xi);
      EXPECT_LT((TwistMatrix(xi).exp() - T.Matrix()).cwiseAbs().maxCoeff(), 1e-13) << angle;
      EXPECT_LT((LogSE3(T) - xi).norm(), 1e-13) << "angle " << angle;
    }
  }
}

TEST_F(PoseRandom, RoundTripNearPi) {
  for (double gap : {1e-3, 1e-6, 1e-9, 1e-12}) {
    for (int i = 0; i < 20; ++i) {
      const Vector6d xi = Twist(RandomUnit() * (M_PI - gap), RandomUnit() * Uniform(0, 10));
      const Pose T = ExpSE3(xi);
      EXPECT_LT((TwistMatrix(xi).exp() - T.Matrix()).cwiseAbs().maxCoeff(), 1e-12);
      const Vector6d back = LogSE3(T);
      EXPECT_NEAR(back.head<3>().norm(), M_PI - gap, 1e-12);
      EXPECT_LT((back - xi).norm(), 1e-8) << "gap " << gap;
      EXPECT_LT(PoseDistance(ExpSE3(back), T), 1e-12);
    }
  }
  // Exactly pi: the axis sign is ambiguous, the pose is not.
  for (int i = 0; i < 20; ++i) {
    const Vector6d xi = Twist(RandomUnit() * M_PI, RandomUnit() * Uniform(0, 10));
    const Pose T = ExpSE3(xi);
    const Vector6d back = LogSE3(T);
    EXPECT_NEAR(back.head<3>().norm(), M_PI, 1e-12);
    EXPECT_TRUE(back.allFinite());
    EXPECT_LT(PoseDistance(ExpSE3(back), T), 1e-12);
  }
}

TEST(Pose, LogSO3TakesTheShortAngle) {
  // q and -q are the same rotation; the log has angle <= pi either way.
  const Eigen::Quaterniond q = ExpSO3(Eigen::Vector3d(0, 0, 0.5));
  Eigen::Quaterniond minus_q(-q.w(), -q.x(), -q.y(), -q.z());
  EXPECT_NEAR((LogSO3(minus_q) - Eigen::Vector3d(0, 0, 0.5)).norm(), 0, 1e-15);
  // A rotation by 1.5 pi about z is a rotation by -0.5 pi.
  const Eigen::Quaterniond r(Eigen::AngleAxisd(1.5 * M_PI, Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR((LogSO3(r) - Eigen::Vector3d(0, 0, -0.5 * M_PI)).norm(), 0, 1e-14);
  // Not normalised input.
  Eigen::Quaterniond scaled = q;
  scaled.coeffs() *= 3.0;
  EXPECT_NEAR((LogSO3(scaled) - Eigen::Vector3d(0, 0, 0.5)).norm(), 0, 1e-15);
}

TEST_F(PoseRandom, CompositionAndInverse) {
  for (int i = 0; i < 100; ++i) {
    const Pose A = RandomPose(), B = RandomPose();
    const Eigen::Vector3d p = RandomUnit() * Uniform(0, 20);
    EXPECT_LT(((A * B) * p - A * (B * p)).norm(), 1e-12);
    EXPECT_LT(((A * B).Matrix() - A.Matrix() * B.Matrix()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT(PoseDistance(A * A.Inverse(), Pose::Identity()), 1e-14);
    EXPECT_LT(PoseDistance(A.Inverse() * A, Pose::Identity()), 1e-14);
    EXPECT_LT((A.Inverse().Matrix() - A.Matrix().inverse()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((A.Center() - A.Inverse().t).norm(), 1e-13);
    EXPECT_LT((A * A.Center()).norm(), 1e-12);  // the centre maps to the device origin
    // exp(-xi) is the inverse of exp(xi).
    const Vector6d xi = LogSE3(A);
    EXPECT_LT(PoseDistance(ExpSE3(-xi), A.Inverse()), 1e-12);
  }
}

TEST_F(PoseRandom, MatrixRoundTrip) {
  for (int i = 0; i < 100; ++i) {
    const Pose A = RandomPose();
    const Pose B = Pose::FromMatrix(A.Matrix());
    EXPECT_LT(PoseDistance(A, B), 1e-14);
    EXPECT_EQ(A.Matrix().row(3), Eigen::RowVector4d(0, 0, 0, 1));
  }
}

TEST(Pose, FromMatrixProjectsOntoARotation) {
  // A rotation printed with 6 digits is not exactly orthonormal.
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() << 0.707107, -0.707107, 0, 0.707107, 0.707107, 0, 0, 0, 1;
  m.topRightCorner<3, 1>() << 1, 2, 3;
  const Pose T = Pose::FromMatrix(m);
  const Eigen::Matrix3d R = T.R();
  EXPECT_LT((R * R.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-14);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-14);
  EXPECT_NEAR(RotationAngleDeg(T.q, Eigen::Quaterniond::Identity()), 45.0, 1e-4);
  EXPECT_EQ(T.t, Eigen::Vector3d(1, 2, 3));

  m(0, 0) = std::nan("");
  EXPECT_THROW(Pose::FromMatrix(m), Error);
}

TEST_F(PoseRandom, InterpolateEndpointsAndMidpoint) {
  for (int i = 0; i < 100; ++i) {
    const Pose a = RandomPose(), b = RandomPose();
    EXPECT_LT(PoseDistance(Interpolate(a, b, 0.0), a), 1e-14);
    EXPECT_LT(PoseDistance(Interpolate(a, b, 1.0), b), 1e-14);
    const Pose mid = Interpolate(a, b, 0.5);
    EXPECT_LT((mid.t - 0.5 * (a.t + b.t)).norm(), 1e-14);
    // Halfway on the shorter arc: equal angles to both ends, summing to the total.
    const double total = RotationAngleDeg(a.q, b.q);
    EXPECT_NEAR(RotationAngleDeg(a.q, mid.q), total / 2, 1e-9);
    EXPECT_NEAR(RotationAngleDeg(mid.q, b.q), total / 2, 1e-9);
    // The sign of a quaternion does not change the path.
    Pose b_flipped = b;
    b_flipped.q.coeffs() *= -1.0;
    EXPECT_LT(PoseDistance(Interpolate(a, b_flipped, 0.3), Interpolate(a, b, 0.3)), 1e-12);
  }
}

TEST(Pose, InterpolateKnownRotation) {
  const Pose a = Pose::Identity();
  const Pose b(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())),
               Eigen::Vector3d(4, 0, 0));
  const Pose q = Interpolate(a, b, 0.25);
  const Eigen::Quaterniond expected(Eigen::AngleAxisd(M_PI / 8, Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(q.q.angularDistance(expected), 0, 1e-14);
  EXPECT_NEAR((q.t - Eigen::Vector3d(1, 0, 0)).norm(), 0, 1e-15);
}

TEST(Pose, RotationAngleDeg) {
  const Eigen::Quaterniond id = Eigen::Quaterniond::Identity();
  const Eigen::Quaterniond rz30(Eigen::AngleAxisd(M_PI / 6, Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(RotationAngleDeg(id, rz30), 30.0, 1e-12);
  EXPECT_NEAR(RotationAngleDeg(rz30, id), 30.0, 1e-12);
  Eigen::Quaterniond minus = rz30;
  minus.coeffs() *= -1.0;
  EXPECT_NEAR(RotationAngleDeg(rz30, minus), 0.0, 1e-12);
  // Accurate at tiny angles (acos would give 0 or 1.2e-6 degrees here).
  const Eigen::Quaterniond tiny(Eigen::AngleAxisd(1e-9, Eigen::Vector3d::UnitX()));
  EXPECT_NEAR(RotationAngleDeg(id, tiny), 1e-9 * 180 / M_PI, 1e-20);
  const Eigen::Quaterniond half_turn(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()));
  EXPECT_NEAR(RotationAngleDeg(id, half_turn), 180.0, 1e-12);
}

TEST(Pose, ExpSO3NearZero) {
  const Eigen::Vector3d w(1e-10, -2e-10, 3e-10);
  const Eigen::Quaterniond q = ExpSO3(w);
  EXPECT_NEAR(q.norm(), 1.0, 1e-16);
  EXPECT_NEAR((LogSO3(q) - w).norm(), 0, 1e-24);
  EXPECT_EQ(ExpSO3(Eigen::Vector3d::Zero()).coeffs(), Eigen::Quaterniond::Identity().coeffs());
}

}  // namespace
}  // namespace locforge

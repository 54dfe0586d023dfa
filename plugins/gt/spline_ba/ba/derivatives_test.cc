// Autodiff Jacobians of the residuals against central differences taken in
// the tangent space of each parameter block (through its manifold's Plus).
#include <ceres/manifold.h>
#include <ceres/product_manifold.h>
#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "cost_functions.h"

namespace locforge::sfm {
namespace {

using Blocks = std::vector<std::vector<double>>;

// Max over blocks and columns of |J_auto - J_numeric| (column norm) relative
// to the largest entry of the whole Jacobian, with J in the tangent space of
// each block (a block whose derivative nearly vanishes, e.g. the first
// control pose at u = 1, would otherwise compare roundoff with roundoff).
double MaxRelativeJacobianError(const ceres::CostFunction& f, const Blocks& x,
                                 const std::vector<const ceres::Manifold*>& manifolds) {
  const int nr = f.num_residuals();
  std::vector<const double*> params;
  for (const auto& b : x) params.push_back(b.data());
  std::vector<std::vector<double>> jac(x.size());
  std::vector<double*> jac_ptrs;
  for (size_t i = 0; i < x.size(); ++i) {
    jac[i].resize(nr * x[i].size());
    jac_ptrs.push_back(jac[i].data());
  }
  std::vector<double> r0(nr);
  EXPECT_TRUE(f.Evaluate(params.data(), r0.data(), jac_ptrs.data()));
  // Scale: the largest column norm of the whole Jacobian.
  double scale = 1e-8;
  for (size_t i = 0; i < x.size(); ++i)
    for (int j = 0; j < nr * static_cast<int>(x[i].size()); ++j) scale = std::max(scale, std::abs(jac[i][j]));
  double worst = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    const int n = static_cast<int>(x[i].size());
    const ceres::Manifold* m = manifolds[i];
    const int tn = m ? m->TangentSize() : n;
    using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    RowMajor plus_jac = RowMajor::Identity(n, tn);  // Ceres' Jacobians are row-major
    if (m) m->PlusJacobian(x[i].data(), plus_jac.data());
    const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> J(jac[i].data(), nr, n);
    const Eigen::MatrixXd J_auto = J * plus_jac;
    for (int k = 0; k < tn; ++k) {
      Eigen::VectorXd col(nr);
      const double h = 1e-6 * std::max(1.0, Eigen::Map<const Eigen::VectorXd>(x[i].data(), n).cwiseAbs().maxCoeff());
      std::vector<double> rp(nr), rm(nr);
      for (int sign : {1, -1}) {
        Eigen::VectorXd delta = Eigen::VectorXd::Zero(tn);
        delta(k) = sign * h;
        std::vector<double> moved(n);
        if (m) {
          m->Plus(x[i].data(), delta.data(), moved.data());
        } else {
          for (int j = 0; j < n; ++j) moved[j] = x[i][j] + delta(j);
        }
        std::vector<const double*> p = params;
        p[i] = moved.data();
        EXPECT_TRUE(f.Evaluate(p.data(), sign > 0 ? rp.data() : rm.data(), nullptr));
      }
      for (int j = 0; j < nr; ++j) col(j) = (rp[j] - rm[j]) / (2 * h);
      worst = std::max(worst, (J_auto.col(k) - col).norm() / scale);
    }
  }
  return worst;
}

std::vector<double> QuatArray(const Eigen::Quaterniond& q) { return {q.x(), q.y(), q.z(), q.w()}; }
std::vector<double> PoseArray(const Pose& p) {
  std::vector<double> a(7);
  PoseToArray(p, a.data());
  return a;
}

TEST(Derivatives, ReprojectionErrorOfEveryModel) {
  std::mt19937 rng(4);
  std::normal_distribution<double> n(0, 1);
  ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>> se3;
  const std::vector<std::pair<CameraModelId, std::vector<double>>> cameras = {
      {CameraModelId::kSimplePinhole, {400, 320, 250}},
      {CameraModelId::kPinhole, {400, 410, 320, 250}},
      {CameraModelId::kSimpleRadial, {400, 320, 250, -0.05}},
      {CameraModelId::kRadial, {400, 320, 250, -0.05, 0.01}},
      {CameraModelId::kOpenCV, {400, 410, 320, 250, -0.05, 0.01, 0.001, -0.002}}};
  for (const auto& [model, params] : cameras) {
    for (int trial = 0; trial < 10; ++trial) {
      const Pose T_wc(ExpSO3(Eigen::Vector3d(n(rng), n(rng), n(rng))), Eigen::Vector3d(n(rng), n(rng), n(rng)));
      const Eigen::Vector3d X = T_wc * Eigen::Vector3d(0.5 * n(rng), 0.5 * n(rng), 3 + std::abs(n(rng)));
      std::unique_ptr<ceres::CostFunction> f(CreateReprojectionError(model, Eigen::Vector2d(300, 200)));
      ASSERT_TRUE(f);
      const Blocks x = {PoseArray(T_wc), {X.x(), X.y(), X.z()}, params};
      EXPECT_LT(MaxRelativeJacobianError(*f, x, {&se3, nullptr, nullptr}), 1e-6)
          << static_cast<int>(model);
    }
  }
}

// The spline residuals, on random control poses and also on identical
// consecutive ones (Omega = 0: the small-angle branches).
TEST(Derivatives, SplinePoseAndSampleErrors) {
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0, 1);
  ceres::EigenQuaternionManifold quaternion;
  ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>> se3;
  auto random_twist = [&](double s) {
    Vector6d xi;
    for (int k = 0; k < 6; ++k) xi(k) = s * n(rng);
    return xi;
  };
  for (int trial = 0; trial < 20; ++trial) {
    const bool degenerate = trial % 4 == 0;
    const Pose base = ExpSE3(random_twist(1.0));
    Pose c[4] = {base, base, base, base};
    if (!degenerate)
      for (int j = 1; j < 4; ++j) c[j] = c[j - 1] * ExpSE3(random_twist(0.2));
    const double u = trial % 5 == 1 ? 0.0 : std::uniform_real_distribution<double>(0, 1)(rng);
    const Pose T_bc = ExpSE3(random_twist(0.5));
    SE3Spline spline;
    spline.t0 = 0;
    spline.dt = 1;
    spline.control.assign(c, c + 4);
    const Pose T_wc = spline.Evaluate(u) * T_bc * ExpSE3(random_twist(degenerate ? 0.0 : 0.05));
    const Vector6d w = SqrtInformation(0.002, 0.01);
    std::unique_ptr<ceres::CostFunction> prior(SplinePoseError::Create(u, 0.1, T_bc.t, w));
    const Blocks x = {PoseArray(c[0]), PoseArray(c[1]), PoseArray(c[2]), PoseArray(c[3]),
                      PoseArray(T_wc), QuatArray(T_bc.q), {degenerate ? 0.0 : 0.004 * n(rng)}};
    EXPECT_LT(MaxRelativeJacobianError(*prior, x, {&se3, &se3, &se3, &se3, &se3, &quaternion, nullptr}), 1e-6)
        << trial;
    std::unique_ptr<ceres::CostFunction> sample(
        SplineSampleError::Create(u, spline.Evaluate(u) * ExpSE3(random_twist(0.01)), w));
    const Blocks xs(x.begin(), x.begin() + 4);
    EXPECT_LT(MaxRelativeJacobianError(*sample, xs, {&se3, &se3, &se3, &se3}), 1e-6) << trial;
    std::unique_ptr<ceres::CostFunction> aligned(
        SplineSampleError::CreateAligned(u, spline.Evaluate(u) * ExpSE3(random_twist(0.01)), w));
    Blocks xa = xs;
    xa.push_back(PoseArray(ExpSE3(random_twist(degenerate ? 0.0 : 0.05))));
    EXPECT_LT(MaxRelativeJacobianError(*aligned, xa, {&se3, &se3, &se3, &se3, &se3}), 1e-6) << trial;
    // The scaled forms: the sample's translation times exp(log-scale).
    const Pose measured = spline.Evaluate(u) * ExpSE3(random_twist(0.01));
    const std::vector<double> log_scale = {degenerate ? 0.0 : 0.01 * n(rng)};
    std::unique_ptr<ceres::CostFunction> scaled(ScaledSplineSampleError::Create(u, measured, w));
    Blocks xsc = xs;
    xsc.push_back(log_scale);
    EXPECT_LT(MaxRelativeJacobianError(*scaled, xsc, {&se3, &se3, &se3, &se3, nullptr}), 1e-6) << trial;
    std::unique_ptr<ceres::CostFunction> scaled_aligned(ScaledSplineSampleError::CreateAligned(u, measured, w));
    Blocks xsa = xa;
    xsa.push_back(log_scale);
    EXPECT_LT(MaxRelativeJacobianError(*scaled_aligned, xsa, {&se3, &se3, &se3, &se3, &se3, nullptr}), 1e-6) << trial;
    std::unique_ptr<ceres::CostFunction> smooth(ControlSmoothnessError::Create(w));
    const Blocks x3(x.begin(), x.begin() + 3);
    EXPECT_LT(MaxRelativeJacobianError(*smooth, x3, {&se3, &se3, &se3}), 1e-6) << trial;
    // Wheeled-base kinematics (non-degenerate controls: a moving segment).
    if (!degenerate) {
      std::unique_ptr<ceres::CostFunction> kinematic(NonholonomicError::Create(0.3, 0.003));
      EXPECT_LT(MaxRelativeJacobianError(*kinematic, xs, {&se3, &se3, &se3, &se3}), 1e-6) << trial;
    }
  }
}

}  // namespace
}  // namespace locforge::sfm

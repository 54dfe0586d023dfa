#include "absolute_pose.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "point_uncertainty.h"

namespace locforge::localization {

namespace {

constexpr size_t kMaxLoRefineInliers = 400;

using Poly = std::vector<double>;  // coefficients, lowest degree first

Poly Multiply(const Poly& a, const Poly& b) {
  Poly out(a.size() + b.size() - 1, 0.0);
  for (size_t i = 0; i < a.size(); ++i)
    for (size_t j = 0; j < b.size(); ++j) out[i + j] += a[i] * b[j];
  return out;
}

Poly Add(Poly a, const Poly& b, double scale = 1.0) {
  if (a.size() < b.size()) a.resize(b.size(), 0.0);
  for (size_t i = 0; i < b.size(); ++i) a[i] += scale * b[i];
  return a;
}

double Evaluate(const Poly& p, double x) {
  double y = 0;
  for (size_t i = p.size(); i-- > 0;) y = y * x + p[i];
  return y;
}

// Real roots of a polynomial (companion matrix eigenvalues, Newton-polished).
std::vector<double> RealRoots(Poly p) {
  while (!p.empty() && std::abs(p.back()) < 1e-14 * (1 + std::abs(p.front()))) p.pop_back();
  const int degree = static_cast<int>(p.size()) - 1;
  std::vector<double> roots;
  if (degree < 1) return roots;
  Eigen::MatrixXd companion = Eigen::MatrixXd::Zero(degree, degree);
  for (int i = 0; i < degree; ++i) companion(0, i) = -p[degree - 1 - i] / p[degree];
  for (int i = 1; i < degree; ++i) companion(i, i - 1) = 1;
  Eigen::EigenSolver<Eigen::MatrixXd> solver(companion, false);
  Poly derivative;
  for (int i = 1; i <= degree; ++i) derivative.push_back(i * p[i]);
  for (int i = 0; i < degree; ++i) {
    const std::complex<double> r = solver.eigenvalues()[i];
    if (std::abs(r.imag()) > 1e-6 * (1 + std::abs(r.real()))) continue;
    double x = r.real();
    for (int k = 0; k < 5; ++k) {
      const double d = Evaluate(derivative, x);
      if (std::abs(d) < 1e-300) break;
      x -= Evaluate(p, x) / d;
    }
    roots.push_back(x);
  }
  return roots;
}

// R, t minimising sum |camera_i - (R world_i + t)|^2 (Kabsch, no scale).
bool AlignPoints(const std::vector<Eigen::Vector3d>& world,
                 const std::vector<Eigen::Vector3d>& camera, Pose* camera_from_world) {
  const size_t n = world.size();
  Eigen::Vector3d cw = Eigen::Vector3d::Zero(), cc = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    cw += world[i];
    cc += camera[i];
  }
  cw /= n;
  cc /= n;
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) h += (world[i] - cw) * (camera[i] - cc).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
  const Eigen::Matrix3d r = svd.matrixV() * d * svd.matrixU().transpose();
  if (!r.allFinite()) return false;
  *camera_from_world = Pose(Eigen::Quaterniond(r), cc - r * cw);
  return true;
}

struct ReprojectionCost {
  ReprojectionCost(const Eigen::Vector2d& observed, const Eigen::Vector3d& world,
                   const Pose& camera_from_rig, double focal, const Eigen::Matrix2d& whitening)
      : observed_(observed), world_(world), focal_(focal), whitening_(whitening) {
    const Eigen::Matrix3d r = camera_from_rig.R();
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) r_cr_[3 * i + j] = r(i, j);
      t_cr_[i] = camera_from_rig.t[i];
    }
  }
  template <typename T>
  bool operator()(const T* q, const T* t, T* residual) const {
    const T x[3] = {T(world_[0]), T(world_[1]), T(world_[2])};
    T rig[3];
    ceres::UnitQuaternionRotatePoint(q, x, rig);
    for (int i = 0; i < 3; ++i) rig[i] += t[i];
    T cam[3];
    for (int i = 0; i < 3; ++i)
      cam[i] = T(r_cr_[3 * i]) * rig[0] + T(r_cr_[3 * i + 1]) * rig[1] +
               T(r_cr_[3 * i + 2]) * rig[2] + T(t_cr_[i]);
    const T e0 = T(focal_) * (cam[0] / cam[2] - T(observed_[0]));
    const T e1 = T(focal_) * (cam[1] / cam[2] - T(observed_[1]));
    residual[0] = T(whitening_(0, 0)) * e0 + T(whitening_(0, 1)) * e1;
    residual[1] = T(whitening_(1, 0)) * e0 + T(whitening_(1, 1)) * e1;
    return true;
  }
  Eigen::Vector2d observed_;
  Eigen::Vector3d world_;
  double r_cr_[9];
  double t_cr_[3];
  double focal_;
  Eigen::Matrix2d whitening_;
};

std::vector<int> InliersOf(const std::vector<Correspondence>& cs,
                           const std::vector<RigCamera>& cameras, const Pose& pose,
                           double threshold_sq, double* score) {
  std::vector<int> inliers;
  double s = 0;
  for (size_t i = 0; i < cs.size(); ++i) {
    const double e = SquaredReprojectionError(pose, cameras[cs[i].camera], cs[i]);
    if (e <= threshold_sq) inliers.push_back(static_cast<int>(i));
    s += std::min(e, threshold_sq);
  }
  if (score) *score = s;
  return inliers;
}

// Per-axis sigma of the inliers' reprojection noise, pixels: the median
// residual norm of 2D Gaussian noise is sigma sqrt(2 ln 2) (Rayleigh).
double InlierNoiseSigmaPx(const std::vector<Correspondence>& cs, const std::vector<RigCamera>& cameras,
                          const Pose& pose, const std::vector<int>& inliers) {
  if (inliers.empty()) return 0;
  std::vector<double> norms;
  norms.reserve(inliers.size());
  for (int i : inliers) norms.push_back(std::sqrt(SquaredReprojectionError(pose, cameras[cs[i].camera], cs[i])));
  std::nth_element(norms.begin(), norms.begin() + norms.size() / 2, norms.end());
  return norms[norms.size() / 2] / std::sqrt(2 * std::log(2.0));
}

std::vector<Correspondence> Subset(const std::vector<Correspondence>& cs,
                                   const std::vector<int>& idx) {
  std::vector<Correspondence> out;
  out.reserve(idx.size());
  for (int i : idx) out.push_back(cs[i]);
  return out;
}

}  // namespace

std::vector<Pose> SolveP3P(const std::vector<Eigen::Vector3d>& bearings_in,
                           const std::vector<Eigen::Vector3d>& points) {
  std::vector<Pose> out;
  if (bearings_in.size() != 3 || points.size() != 3) return out;
  Eigen::Vector3d j[3];
  for (int i = 0; i < 3; ++i) j[i] = bearings_in[i].normalized();
  const double a2 = (points[1] - points[2]).squaredNorm();
  const double b2 = (points[0] - points[2]).squaredNorm();
  const double c2 = (points[0] - points[1]).squaredNorm();
  if (a2 < 1e-18 || b2 < 1e-18 || c2 < 1e-18) return out;
  if ((points[1] - points[0]).cross(points[2] - points[0]).norm() < 1e-12 * (a2 + b2 + c2))
    return out;  // collinear
  const double cos_a = j[1].dot(j[2]), cos_b = j[0].dot(j[2]), cos_g = j[0].dot(j[1]);
  // With s2 = u s1 and s3 = v s1 the law of cosines gives
  //   b2 (1 + u^2 - 2 u cos_g) = c2 (1 + v^2 - 2 v cos_b)          (1)
  //   b2 (u^2 + v^2 - 2 u v cos_a) = a2 (1 + v^2 - 2 v cos_b)      (2)
  // (1) - (2) is linear in u: u = N(v) / D(v); substituting into (1) leaves
  // a quartic in v.
  const Poly q = {1, -2 * cos_b, 1};                                    // 1 + v^2 - 2 v cos_b
  const Poly n = Add(Poly{b2, 0, -b2}, q, a2 - c2);                     // N(v)
  const Poly d = {2 * b2 * cos_g, -2 * b2 * cos_a};                     // D(v)
  Poly quartic = Multiply(n, n);
  quartic = Add(quartic, Multiply(n, d), -2 * cos_g);
  quartic = Add(quartic, Multiply(Add(Poly{1}, q, -c2 / b2), Multiply(d, d)));
  for (double& x : quartic) x *= b2;  // (1) multiplied through by D^2 / b2 * b2
  for (const double v : RealRoots(quartic)) {
    if (v <= 0) continue;
    const double dv = Evaluate(d, v);
    if (std::abs(dv) < 1e-14) continue;
    const double u = Evaluate(n, v) / dv;
    if (u <= 0) continue;
    const double denom = 1 + v * v - 2 * v * cos_b;
    if (denom <= 0) continue;
    const double s1 = std::sqrt(b2 / denom);
    // Newton on the three law-of-cosines equations: a root of the quartic
    // near a double root loses digits, this restores them.
    Eigen::Vector3d s(s1, u * s1, v * s1);
    for (int k = 0; k < 5; ++k) {
      const Eigen::Vector3d f(s(1) * s(1) + s(2) * s(2) - 2 * s(1) * s(2) * cos_a - a2,
                              s(0) * s(0) + s(2) * s(2) - 2 * s(0) * s(2) * cos_b - b2,
                              s(0) * s(0) + s(1) * s(1) - 2 * s(0) * s(1) * cos_g - c2);
      Eigen::Matrix3d jac;
      jac << 0, 2 * s(1) - 2 * s(2) * cos_a, 2 * s(2) - 2 * s(1) * cos_a,
          2 * s(0) - 2 * s(2) * cos_b, 0, 2 * s(2) - 2 * s(0) * cos_b,
          2 * s(0) - 2 * s(1) * cos_g, 2 * s(1) - 2 * s(0) * cos_g, 0;
      const Eigen::Vector3d step = jac.partialPivLu().solve(f);
      if (!step.allFinite()) break;
      s -= step;
    }
    if (!s.allFinite() || s.minCoeff() <= 0) continue;
    const std::vector<Eigen::Vector3d> camera = {s(0) * j[0], s(1) * j[1], s(2) * j[2]};
    Pose pose;
    if (AlignPoints(points, camera, &pose)) out.push_back(pose);
  }
  return out;
}

bool SolveEPnP(const std::vector<Eigen::Vector2d>& normalized,
               const std::vector<Eigen::Vector3d>& points, Pose* camera_from_world) {
  const size_t n = points.size();
  if (n < 4 || normalized.size() != n) return false;
  // Control points: the centroid and the principal directions.
  Eigen::Vector3d c0 = Eigen::Vector3d::Zero();
  for (const auto& p : points) c0 += p;
  c0 /= n;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : points) cov += (p - c0) * (p - c0).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> pca(cov);
  const Eigen::Vector3d lambda = pca.eigenvalues();
  if (lambda(0) <= 1e-12 * lambda(2)) return false;  // planar or degenerate
  Eigen::Vector3d control[4];
  control[0] = c0;
  Eigen::Matrix3d basis;
  for (int k = 0; k < 3; ++k) {
    control[k + 1] = c0 + std::sqrt(lambda(k) / n) * pca.eigenvectors().col(k);
    basis.col(k) = control[k + 1] - c0;
  }
  const Eigen::Matrix3d basis_inv = basis.inverse();
  std::vector<Eigen::Vector4d> alphas(n);
  Eigen::MatrixXd m(2 * n, 12);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d a = basis_inv * (points[i] - c0);
    alphas[i] << 1 - a.sum(), a(0), a(1), a(2);
    for (int k = 0; k < 4; ++k) {
      m.block<2, 3>(2 * i, 3 * k) << alphas[i](k), 0, -alphas[i](k) * normalized[i].x(), 0,
          alphas[i](k), -alphas[i](k) * normalized[i].y();
    }
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> null_space(m.transpose() * m);
  const Eigen::Matrix<double, 12, 1> v = null_space.eigenvectors().col(0);
  // Scale from the distances between control points (rigid in both frames).
  double num = 0, den = 0;
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) {
      const double dc = (v.segment<3>(3 * a) - v.segment<3>(3 * b)).norm();
      num += dc * (control[a] - control[b]).norm();
      den += dc * dc;
    }
  if (den <= 0) return false;
  double beta = num / den;
  std::vector<Eigen::Vector3d> camera(n);
  double mean_z = 0;
  for (size_t i = 0; i < n; ++i) {
    camera[i].setZero();
    for (int k = 0; k < 4; ++k) camera[i] += alphas[i](k) * v.segment<3>(3 * k);
    mean_z += camera[i].z();
  }
  if (mean_z < 0) beta = -beta;
  for (auto& x : camera) x *= beta;
  return AlignPoints(points, camera, camera_from_world);
}

double SquaredReprojectionError(const Pose& rig_from_world, const RigCamera& camera,
                                const Correspondence& c) {
  const Eigen::Vector3d p = camera.camera_from_rig * (rig_from_world * c.world);
  if (p.z() <= 1e-12) return std::numeric_limits<double>::infinity();
  return (camera.focal * (p.head<2>() / p.z() - c.normalized)).squaredNorm();
}

bool RefineOptions::Check(std::string* why) const {
  if (cauchy_scale_px <= 0) return *why = "cauchy_scale_px must be > 0", false;
  if (max_iterations < 1) return *why = "max_iterations must be >= 1", false;
  return true;
}

bool RefinePose(const std::vector<Correspondence>& correspondences,
                const std::vector<RigCamera>& cameras, const RefineOptions& options,
                Pose* rig_from_world) {
  if (correspondences.size() < 3) return false;
  double q[4] = {rig_from_world->q.w(), rig_from_world->q.x(), rig_from_world->q.y(),
                 rig_from_world->q.z()};
  double t[3] = {rig_from_world->t.x(), rig_from_world->t.y(), rig_from_world->t.z()};
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  ceres::CauchyLoss loss(options.cauchy_scale_px);
  for (const auto& c : correspondences) {
    const RigCamera& cam = cameras[c.camera];
    const Eigen::Matrix2d whitening =
        c.world_covariance.isZero(0) || options.point_covariance_scale <= 0
            ? Eigen::Matrix2d::Identity()
            : ReprojectionWhitening(cam.camera_from_rig * *rig_from_world, cam.focal, c.world,
                                    options.point_covariance_scale * c.world_covariance);
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<ReprojectionCost, 2, 4, 3>(
                                 new ReprojectionCost(c.normalized, c.world, cam.camera_from_rig,
                                                      cam.focal, whitening)),
                             &loss, q, t);
  }
  problem.SetManifold(q, new ceres::QuaternionManifold);
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.num_threads = 1;
  solver_options.logging_type = ceres::SILENT;
  solver_options.function_tolerance = 1e-12;
  solver_options.parameter_tolerance = 1e-12;
  solver_options.gradient_tolerance = 1e-14;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  if (!summary.IsSolutionUsable()) return false;
  const Pose refined(Eigen::Quaterniond(q[0], q[1], q[2], q[3]), Eigen::Vector3d(t[0], t[1], t[2]));
  if (!refined.t.allFinite() || !refined.q.coeffs().allFinite()) return false;
  *rig_from_world = refined;
  return true;
}

bool RansacOptions::Check(std::string* why) const {
  if (max_error_px <= 0) return *why = "max_error_px must be > 0", false;
  if (confidence <= 0 || confidence >= 1) return *why = "confidence must be in (0, 1)", false;
  if (min_iterations < 1 || max_iterations < min_iterations)
    return *why = "need 1 <= min_iterations <= max_iterations", false;
  if (min_inliers < 3) return *why = "min_inliers must be >= 3", false;
  return refine.Check(why);
}

namespace {

// One LO-RANSAC run (P3P samples within one camera of the rig, local
// optimisation of each better hypothesis) and its best pose so far.
struct Ransac {
  Ransac(const std::vector<Correspondence>& cs, const std::vector<RigCamera>& cameras, const RansacOptions& options)
      : cs(cs), cameras(cameras), options(options), th2(options.max_error_px * options.max_error_px),
        by_camera(cameras.size()), rng(options.seed) {}

  const std::vector<Correspondence>& cs;
  const std::vector<RigCamera>& cameras;
  const RansacOptions& options;
  const double th2;
  std::vector<std::vector<int>> by_camera;  // correspondences of each camera
  std::vector<int> sampleable;              // of cameras with 3 or more
  std::mt19937_64 rng;
  double best_score = std::numeric_limits<double>::infinity();
  std::vector<int> best_inliers;
  Pose best_pose;

  void IndexByCamera() {
    for (size_t i = 0; i < cs.size(); ++i) {
      if (cs[i].camera < 0 || cs[i].camera >= static_cast<int>(cameras.size()))
        throw std::invalid_argument("correspondence camera index out of range");
      by_camera[cs[i].camera].push_back(static_cast<int>(i));
    }
    for (size_t i = 0; i < cs.size(); ++i)
      if (by_camera[cs[i].camera].size() >= 3) sampleable.push_back(static_cast<int>(i));
  }

  // True when pose scores better than the best so far (then it is the best).
  bool Consider(const Pose& pose) {
    double score;
    std::vector<int> inliers = InliersOf(cs, cameras, pose, th2, &score);
    if (score < best_score) {
      best_score = score;
      best_inliers = std::move(inliers);
      best_pose = pose;
      return true;
    }
    return false;
  }

  // The LO refinement only needs to improve the hypothesis: a strided
  // subset of large inlier sets keeps it cheap (the final one uses all).
  std::vector<int> RefinementSubset() const {
    std::vector<int> subset = best_inliers;
    if (subset.size() > kMaxLoRefineInliers) {
      std::vector<int> strided;
      const double step = static_cast<double>(subset.size()) / kMaxLoRefineInliers;
      for (size_t k = 0; k < kMaxLoRefineInliers; ++k) strided.push_back(subset[static_cast<size_t>(k * step)]);
      subset.swap(strided);
    }
    return subset;
  }

  // Local optimisation: refit on the inliers while they grow (EPnP when they
  // are all of one camera, then the robust refinement).
  void OptimiseLocally() {
    for (int round = 0; round < 4; ++round) {
      const size_t before = best_inliers.size();
      if (before < 6) return;
      const auto inliers = Subset(cs, best_inliers);
      bool single_camera = true;
      for (const auto& c : inliers) single_camera &= c.camera == inliers.front().camera;
      if (single_camera) {
        std::vector<Eigen::Vector2d> xs;
        std::vector<Eigen::Vector3d> ps;
        for (const auto& c : inliers) {
          xs.push_back(c.normalized);
          ps.push_back(c.world);
        }
        Pose camera_from_world;
        if (SolveEPnP(xs, ps, &camera_from_world))
          Consider(cameras[inliers.front().camera].camera_from_rig.Inverse() * camera_from_world);
      }
      Pose refined = best_pose;
      if (RefinePose(Subset(cs, RefinementSubset()), cameras, options.refine, &refined)) Consider(refined);
      if (best_inliers.size() <= before) return;
    }
  }

  // Three distinct correspondences of one camera, the first drawn from all
  // sampleable ones: false when the camera's pool gave no distinct three.
  bool DrawSample(std::uniform_int_distribution<size_t>& pick_first, int sample[3]) {
    const int first = sampleable[pick_first(rng)];
    const auto& pool = by_camera[cs[first].camera];
    std::uniform_int_distribution<size_t> pick(0, pool.size() - 1);
    sample[0] = sample[1] = sample[2] = first;
    for (int k = 1; k < 3; ++k) {
      for (int tries = 0; tries < 100; ++tries) {
        const int candidate = pool[pick(rng)];
        if (candidate != sample[0] && candidate != sample[1]) {
          sample[k] = candidate;
          break;
        }
      }
    }
    return !(sample[1] == sample[0] || sample[2] == sample[0] || sample[2] == sample[1]);
  }

  // The P3P poses of a sample, each considered: true when one was better.
  bool TrySample(const int sample[3]) {
    std::vector<Eigen::Vector3d> bearings, points;
    for (int k = 0; k < 3; ++k) {
      bearings.push_back(cs[sample[k]].normalized.homogeneous());
      points.push_back(cs[sample[k]].world);
    }
    const Pose& camera_from_rig = cameras[cs[sample[0]].camera].camera_from_rig;
    bool improved = false;
    for (const Pose& camera_from_world : SolveP3P(bearings, points))
      improved |= Consider(camera_from_rig.Inverse() * camera_from_world);
    return improved;
  }

  // Iterations needed for the confidence at the best inlier ratio (RANSAC's
  // stopping rule); `needed` unchanged when no sample can be all inliers.
  void UpdateNeeded(int* needed) const {
    const double w = best_inliers.size() / static_cast<double>(cs.size());
    const double p_good = std::pow(w, 3);
    if (p_good >= 1) {
      *needed = 0;
    } else if (p_good > 0) {
      *needed = static_cast<int>(std::min<double>(
          options.max_iterations, std::ceil(std::log(1 - options.confidence) / std::log(1 - p_good))));
    }
  }

  // The hypothesis loop: how many iterations ran.
  int Sample() {
    int needed = options.max_iterations;
    int iteration = 0;
    std::uniform_int_distribution<size_t> pick_first(0, sampleable.size() - 1);
    for (; iteration < std::max(needed, options.min_iterations) && iteration < options.max_iterations;
         ++iteration) {
      int sample[3];
      if (!DrawSample(pick_first, sample)) continue;
      if (!TrySample(sample)) continue;
      OptimiseLocally();
      UpdateNeeded(&needed);
    }
    return iteration;
  }

  // Final refinement on all inliers, then inliers measured again. The
  // refinement lowers the robust cost from RANSAC's pose, so it is kept even
  // when a few inliers move past the threshold: counting them is the coarser
  // criterion, and refusing the refined pose would keep a less accurate one.
  void RefineFinal() {
    RefineOptions final_refine = options.refine;
    if (final_refine.noise_factor > 0)
      final_refine.cauchy_scale_px =
          std::max(final_refine.cauchy_scale_px,
                   final_refine.noise_factor * InlierNoiseSigmaPx(cs, cameras, best_pose, best_inliers));
    Pose refined = best_pose;
    if (RefinePose(Subset(cs, best_inliers), cameras, final_refine, &refined)) {
      best_pose = refined;
      best_inliers = InliersOf(cs, cameras, refined, th2, nullptr);
    }
  }

  // The best pose with its inliers into `result`, and the verdict on them.
  void Report(AbsolutePoseResult* result) const {
    const double n = static_cast<double>(cs.size());
    result->rig_from_world = best_pose;
    result->num_inliers = static_cast<int>(best_inliers.size());
    result->inlier_mask.assign(cs.size(), 0);
    double sum = 0;
    for (int i : best_inliers) {
      result->inlier_mask[i] = 1;
      sum += std::sqrt(SquaredReprojectionError(best_pose, cameras[cs[i].camera], cs[i]));
    }
    result->mean_inlier_error_px = sum / std::max<size_t>(1, best_inliers.size());
    if (result->num_inliers < options.min_inliers) {
      result->failure = "only " + std::to_string(result->num_inliers) + " inliers (min_inliers " +
                        std::to_string(options.min_inliers) + ")";
      return;
    }
    if (result->num_inliers < options.min_inlier_ratio * n) {
      result->failure =
          "inlier ratio " + std::to_string(result->num_inliers / n) + " below min_inlier_ratio";
      return;
    }
    result->success = true;
  }
};

}  // namespace

AbsolutePoseResult EstimateAbsolutePose(const std::vector<Correspondence>& cs,
                                        const std::vector<RigCamera>& cameras,
                                        const RansacOptions& options) {
  AbsolutePoseResult result;
  Ransac ransac(cs, cameras, options);
  ransac.IndexByCamera();
  if (static_cast<int>(cs.size()) < options.min_inliers || ransac.sampleable.empty()) {
    result.failure = "too few 2D-3D correspondences (" + std::to_string(cs.size()) + ")";
    return result;
  }
  result.iterations = ransac.Sample();
  if (ransac.best_inliers.size() < 3) {
    result.failure = "RANSAC found no pose with 3 or more inliers";
    return result;
  }
  ransac.RefineFinal();
  ransac.Report(&result);
  return result;
}

}  // namespace locforge::localization

#include "spline.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "cost_functions.h"

namespace locforge::sfm {

void PoseToArray(const Pose& p, double* a) {
  a[0] = p.q.x();
  a[1] = p.q.y();
  a[2] = p.q.z();
  a[3] = p.q.w();
  a[4] = p.t.x();
  a[5] = p.t.y();
  a[6] = p.t.z();
}

Pose PoseFromArray(const double* a) {
  return Pose(Eigen::Quaterniond(a[3], a[0], a[1], a[2]), Eigen::Vector3d(a[4], a[5], a[6]));
}

void SE3Spline::Locate(double t, int* segment, double* u) const {
  const double x = (t - t0) / dt;
  const int last = std::max(0, NumSegments() - 1);
  const int s = std::clamp(static_cast<int>(std::floor(x)), 0, last);
  *segment = s;
  *u = std::clamp(x - s, 0.0, 1.0);
}

Pose SE3Spline::Evaluate(double t) const {
  int s;
  double u;
  Locate(t, &s, &u);
  std::array<std::array<double, 7>, 4> c;
  for (int j = 0; j < 4; ++j) PoseToArray(control[s + j], c[j].data());
  const PoseT<double> p = EvaluateSegment(c[0].data(), c[1].data(), c[2].data(), c[3].data(), u);
  return Pose(p.q, p.t);
}

SE3Spline SE3Spline::Fit(const std::vector<double>& times_s, const std::vector<Pose>& T_world_body,
                         double knot_spacing_s) {
  const double inf = std::numeric_limits<double>::infinity();
  return Fit(times_s, T_world_body, knot_spacing_s, inf, -inf);
}

SE3Spline SE3Spline::Fit(const std::vector<double>& times_s, const std::vector<Pose>& T_world_body,
                         double knot_spacing_s, double t_begin, double t_end) {
  SE3Spline spline;
  spline.dt = knot_spacing_s;
  const size_t n = std::min(times_s.size(), T_world_body.size());
  if (n == 0 || !(knot_spacing_s > 0)) return spline;
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return times_s[a] < times_s[b]; });
  const double first = times_s[order.front()], last = times_s[order.back()];
  spline.t0 = std::min(first, t_begin);
  const double end = std::max(last, t_end);
  const int segments = std::max(1, static_cast<int>(std::ceil((end - spline.t0) / spline.dt - 1e-9)));

  // Initial control poses: the samples interpolated at the control centre
  // times t0 + (k-1) dt, clamped to the sampled range.
  auto sample_at = [&](double t) {
    if (t <= first) return T_world_body[order.front()];
    if (t >= last) return T_world_body[order.back()];
    size_t hi = std::upper_bound(order.begin(), order.end(), t,
                                 [&](double v, size_t i) { return v < times_s[i]; }) - order.begin();
    const size_t a = order[hi - 1], b = order[hi];
    const double span = times_s[b] - times_s[a];
    return Interpolate(T_world_body[a], T_world_body[b], span > 0 ? (t - times_s[a]) / span : 0.0);
  };
  spline.control.resize(segments + 3);
  for (int k = 0; k < segments + 3; ++k) spline.control[k] = sample_at(spline.t0 + (k - 1) * spline.dt);
  // Keep neighbouring quaternions in one hemisphere (cosmetic; Log picks the short arc).
  for (size_t k = 1; k < spline.control.size(); ++k)
    if (spline.control[k].q.coeffs().dot(spline.control[k - 1].q.coeffs()) < 0)
      spline.control[k].q.coeffs() *= -1;

  // Least-squares fit to the samples (1 cm ~ 0.01 rad), a weak smoothness
  // term (second differences, sigma 0.1 per knot; zero on constant twists)
  // and a very weak pull (sigma 1000) to the init.
  std::vector<std::array<double, 7>> c(spline.control.size());
  for (size_t k = 0; k < c.size(); ++k) PoseToArray(spline.control[k], c[k].data());
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>> manifold;
  const Eigen::Matrix<double, 6, 1> w_sample = SqrtInformation(0.01, 0.01);
  const Eigen::Matrix<double, 6, 1> w_control = SqrtInformation(1e3, 1e3);
  for (size_t i = 0; i < n; ++i) {
    int s;
    double u;
    spline.Locate(times_s[i], &s, &u);
    problem.AddResidualBlock(SplineSampleError::Create(u, T_world_body[i], w_sample), nullptr,
                             c[s].data(), c[s + 1].data(), c[s + 2].data(), c[s + 3].data());
  }
  const Eigen::Matrix<double, 6, 1> w_smooth = SqrtInformation(0.1, 0.1);
  for (size_t k = 1; k + 1 < c.size(); ++k)
    problem.AddResidualBlock(ControlSmoothnessError::Create(w_smooth), nullptr, c[k - 1].data(), c[k].data(),
                             c[k + 1].data());
  for (size_t k = 0; k < c.size(); ++k) {
    problem.AddResidualBlock(ControlPoseError::Create(spline.control[k], w_control), nullptr, c[k].data());
    problem.SetManifold(c[k].data(), &manifold);
  }
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.max_num_iterations = 50;
  options.function_tolerance = 1e-14;
  options.gradient_tolerance = 1e-16;
  options.parameter_tolerance = 1e-12;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (summary.IsSolutionUsable())
    for (size_t k = 0; k < c.size(); ++k) spline.control[k] = PoseFromArray(c[k].data());
  return spline;
}

}  // namespace locforge::sfm

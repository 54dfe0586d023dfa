// The spline bundle adjustment of spline_ba.h (paper section 3.2).
#include "spline_ba.h"

#include <ceres/ceres.h>

#include <Eigen/QR>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <memory>
#include <memory_resource>
#include <optional>
#include <sstream>

#include "cost_functions.h"

namespace locforge::sfm {

std::string SplineBAOptions::CheckMessage() const {
  auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (!positive(knot_spacing_s)) return "knot_spacing_s must be > 0";
  if (!positive(prior_sigma_rotation_rad)) return "prior_sigma_rotation_rad must be > 0";
  if (!positive(prior_sigma_translation_m)) return "prior_sigma_translation_m must be > 0";
  if (!(trajectory_prior_sigma_rotation_rad >= 0) || !std::isfinite(trajectory_prior_sigma_rotation_rad))
    return "trajectory_prior_sigma_rotation_rad must be >= 0 (0: off)";
  if (!(trajectory_prior_sigma_translation_m >= 0) || !std::isfinite(trajectory_prior_sigma_translation_m))
    return "trajectory_prior_sigma_translation_m must be >= 0 (0: off)";
  if (!positive(alignment_sigma_rotation_rad)) return "alignment_sigma_rotation_rad must be > 0";
  if (!positive(alignment_sigma_translation_m)) return "alignment_sigma_translation_m must be > 0";
  if (align_trajectories && !(trajectory_prior_sigma_rotation_rad > 0 && trajectory_prior_sigma_translation_m > 0))
    return "align_trajectories needs the trajectory prior (trajectory_prior_sigma_* > 0)";
  if (scale_trajectories && !(trajectory_prior_sigma_rotation_rad > 0 && trajectory_prior_sigma_translation_m > 0))
    return "scale_trajectories needs the trajectory prior (trajectory_prior_sigma_* > 0)";
  if (!positive(trajectory_scale_sigma)) return "trajectory_scale_sigma must be > 0";
  if (!(nonholonomic_sigma_mps >= 0) || !std::isfinite(nonholonomic_sigma_mps))
    return "nonholonomic_sigma_mps must be >= 0 (0: off)";
  if (!positive(cauchy_scale_px)) return "cauchy_scale_px must be > 0";
  if (max_iterations < 0) return "max_iterations must be >= 0";
  if (!(function_tolerance >= 0) || !(gradient_tolerance >= 0) || !(parameter_tolerance >= 0))
    return "tolerances must be >= 0";
  if (num_threads < 1) return "num_threads must be >= 1";
  if (sparse_schur_max_images < 0) return "sparse_schur_max_images must be >= 0";
  if (!(iterative_eta > 0 && iterative_eta < 1)) return "iterative_eta must be in (0, 1)";
  if (!positive(max_time_offset_s) || max_time_offset_s >= knot_spacing_s)
    return "max_time_offset_s must be in (0, knot_spacing_s)";
  if (linear_solver != "auto" && linear_solver != "sparse_schur" && linear_solver != "iterative_schur")
    return "linear_solver must be auto, sparse_schur or iterative_schur (got '" + linear_solver + "')";
  return "";
}

std::string BAProblem::Validate() const {
  const int nt = static_cast<int>(trajectories.size()), ns = static_cast<int>(sensors.size());
  const int ni = static_cast<int>(images.size()), np = static_cast<int>(points.size());
  for (int t = 0; t < nt; ++t)
    if (trajectories[t].times_s.size() != trajectories[t].T_world_body.size())
      return "trajectory " + std::to_string(t) + ": times_s and T_world_body differ in size";
  for (int s = 0; s < ns; ++s) {
    const Camera& c = sensors[s].camera;
    if (!IsSupportedModel(c.model))
      return "sensor " + std::to_string(s) + ": camera model " + c.info().name +
             " is not supported (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV)";
    const std::string why = c.Validate();
    if (!why.empty()) return "sensor " + std::to_string(s) + ": " + why;
  }
  for (int i = 0; i < ni; ++i) {
    const Image& im = images[i];
    if (im.sensor < 0 || im.sensor >= ns)
      return "image " + std::to_string(i) + " (" + im.name + "): sensor index out of range";
    if (im.trajectory >= nt || im.trajectory < -1)
      return "image " + std::to_string(i) + " (" + im.name + "): trajectory index out of range";
    if (im.trajectory >= 0 && trajectories[im.trajectory].times_s.empty())
      return "image " + std::to_string(i) + " (" + im.name + "): its trajectory has no samples";
  }
  for (size_t k = 0; k < observations.size(); ++k) {
    const Observation& o = observations[k];
    if (o.image < 0 || o.image >= ni || o.point < 0 || o.point >= np)
      return "observation " + std::to_string(k) + ": image or point index out of range";
  }
  return "";
}

namespace {

bool InFront(const BAProblem& problem, const BAProblem::Observation& o, Eigen::Vector2d* xy) {
  const BAProblem::Image& im = problem.images[o.image];
  const Eigen::Vector3d p = im.T_world_camera.Inverse() * problem.points[o.point].xyz;
  if (!(p.z() > 0)) return false;
  *xy = problem.sensors[im.sensor].camera.Project(p);
  return true;
}

// The intrinsics of a camera restricted to a linear subspace, x = x0 + B d:
// fx and fy moving together (fix_aspect_ratio keeps fy / fx at its initial
// value) and/or the principal point held (refine_principal_point = false).
class LinearSubspaceManifold : public ceres::Manifold {
 public:
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  explicit LinearSubspaceManifold(const Eigen::MatrixXd& basis)
      : basis_(basis), pseudo_inverse_(basis.completeOrthogonalDecomposition().pseudoInverse()) {}
  int AmbientSize() const override { return static_cast<int>(basis_.rows()); }
  int TangentSize() const override { return static_cast<int>(basis_.cols()); }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    Eigen::Map<Eigen::VectorXd>(x_plus_delta, AmbientSize()) =
        Eigen::Map<const Eigen::VectorXd>(x, AmbientSize()) +
        basis_ * Eigen::Map<const Eigen::VectorXd>(delta, TangentSize());
    return true;
  }
  bool PlusJacobian(const double*, double* jacobian) const override {
    Eigen::Map<RowMajor>(jacobian, AmbientSize(), TangentSize()) = basis_;
    return true;
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    Eigen::Map<Eigen::VectorXd>(y_minus_x, TangentSize()) =
        pseudo_inverse_ * (Eigen::Map<const Eigen::VectorXd>(y, AmbientSize()) -
                           Eigen::Map<const Eigen::VectorXd>(x, AmbientSize()));
    return true;
  }
  bool MinusJacobian(const double*, double* jacobian) const override {
    Eigen::Map<RowMajor>(jacobian, TangentSize(), AmbientSize()) = pseudo_inverse_;
    return true;
  }

 private:
  Eigen::MatrixXd basis_, pseudo_inverse_;
};

// Basis of the free intrinsics of one camera (columns), empty when nothing
// is restricted (the block then moves freely).
Eigen::MatrixXd IntrinsicsBasis(CameraModelId model, const std::vector<double>& params, bool fix_aspect_ratio,
                                bool refine_principal_point) {
  const int n = static_cast<int>(params.size());
  const int pp = PrincipalPointIndex(model);
  const bool two_focals = pp == 2;  // fx, fy (PINHOLE, OPENCV)
  const bool tie = fix_aspect_ratio && two_focals && params[0] != 0;
  if (!tie && refine_principal_point) return {};
  std::vector<Eigen::VectorXd> columns;
  auto unit = [n](int i) {
    Eigen::VectorXd e = Eigen::VectorXd::Zero(n);
    e(i) = 1;
    return e;
  };
  for (int i = 0; i < n; ++i) {
    if (i == 1 && tie) continue;  // moves with fx
    if ((i == pp || i == pp + 1) && !refine_principal_point) continue;
    Eigen::VectorXd e = unit(i);
    if (i == 0 && tie) e(1) = params[1] / params[0];
    columns.push_back(e);
  }
  Eigen::MatrixXd basis(n, static_cast<int>(columns.size()));
  for (size_t k = 0; k < columns.size(); ++k) basis.col(static_cast<Eigen::Index>(k)) = columns[k];
  return basis;
}

// The parameter blocks. Solved from one buffer (Pack): Ceres keeps each
// elimination group as a set ordered by address, which becomes the reduced
// system's column order, so blocks scattered over the heap made the rounding,
// hence the solution's last bits, depend on the heap layout (two runs of the
// `large` ground truth differed by 0.2 mm; test SameBitsWhateverTheHeapLayout).
struct Parameters {
  explicit Parameters(std::pmr::memory_resource* memory = std::pmr::get_default_resource())
      : image_q(memory), image_t(memory), points(memory), intrinsics(memory), q_body_camera(memory),
        time_offsets(memory), controls(memory), alignments(memory), log_scales(memory) {}
  std::pmr::vector<std::array<double, 4>> image_q;  // q_world_camera, x y z w
  std::pmr::vector<std::array<double, 3>> image_t;  // t_world_camera
  std::pmr::vector<std::array<double, 3>> points;
  std::pmr::vector<std::pmr::vector<double>> intrinsics;
  std::pmr::vector<std::array<double, 4>> q_body_camera;
  std::pmr::vector<double> time_offsets;  // per sensor, seconds
  std::vector<SE3Spline> splines;         // per trajectory (empty control: none); not parameters
  std::pmr::vector<std::pmr::vector<std::array<double, 7>>> controls;
  std::pmr::vector<std::array<double, 7>> alignments;  // per trajectory, world-from-LiDAR-world
  std::pmr::vector<double> log_scales;                 // per trajectory, of its LiDAR samples
};

// Bytes that Pack and the later per-trajectory blocks (alignments, log
// scales) take from the buffer, with room for each allocation's alignment.
size_t PackedBytes(const Parameters& x) {
  size_t doubles = 4 * x.image_q.size() + 3 * x.image_t.size() + 3 * x.points.size() + 4 * x.q_body_camera.size() +
                   x.time_offsets.size() + (7 + 1) * x.controls.size();
  for (const auto& k : x.intrinsics) doubles += k.size();
  for (const auto& c : x.controls) doubles += 7 * c.size();
  const size_t vectors = x.intrinsics.size() + x.controls.size();
  const size_t allocations = 16 + vectors;
  return doubles * sizeof(double) + vectors * sizeof(std::pmr::vector<double>) +
         allocations * alignof(std::max_align_t);
}

// Copies every block into `to`, whose memory resource hands out addresses in
// allocation order: one allocation per container, in this fixed order.
void Pack(const Parameters& from, Parameters* to) {
  to->image_q.assign(from.image_q.begin(), from.image_q.end());
  to->image_t.assign(from.image_t.begin(), from.image_t.end());
  to->points.assign(from.points.begin(), from.points.end());
  to->intrinsics.reserve(from.intrinsics.size());
  for (const auto& k : from.intrinsics) to->intrinsics.emplace_back(k.begin(), k.end());
  to->q_body_camera.assign(from.q_body_camera.begin(), from.q_body_camera.end());
  to->time_offsets.assign(from.time_offsets.begin(), from.time_offsets.end());
  to->splines = from.splines;
  to->controls.reserve(from.controls.size());
  for (const auto& c : from.controls) to->controls.emplace_back(c.begin(), c.end());
}

void CopyIn(const BAProblem& p, Parameters* x) {
  for (const auto& im : p.images) {
    const Eigen::Quaterniond& q = im.T_world_camera.q;
    x->image_q.push_back({q.x(), q.y(), q.z(), q.w()});
    x->image_t.push_back({im.T_world_camera.t.x(), im.T_world_camera.t.y(), im.T_world_camera.t.z()});
  }
  for (const auto& pt : p.points) x->points.push_back({pt.xyz.x(), pt.xyz.y(), pt.xyz.z()});
  for (const auto& s : p.sensors) {
    x->intrinsics.emplace_back(s.camera.params.begin(), s.camera.params.end());
    const Eigen::Quaterniond& q = s.T_body_camera.q;
    x->q_body_camera.push_back({q.x(), q.y(), q.z(), q.w()});
    x->time_offsets.push_back(s.time_offset_s);
  }
}

// Fits one spline per trajectory that has images, covering its samples and
// its images' timestamps.
void FitSplines(const BAProblem& p, double knot_spacing_s, Parameters* x) {
  const size_t nt = p.trajectories.size();
  std::vector<double> begin(nt, std::numeric_limits<double>::infinity());
  std::vector<double> end(nt, -std::numeric_limits<double>::infinity());
  std::vector<int> count(nt, 0);
  for (const auto& im : p.images) {
    if (im.trajectory < 0) continue;
    begin[im.trajectory] = std::min(begin[im.trajectory], im.time_s);
    end[im.trajectory] = std::max(end[im.trajectory], im.time_s);
    ++count[im.trajectory];
  }
  x->splines.resize(nt);
  x->controls.resize(nt);
  for (size_t t = 0; t < nt; ++t) {
    if (!count[t]) continue;
    const auto& tr = p.trajectories[t];
    x->splines[t] = SE3Spline::Fit(tr.times_s, tr.T_world_body, knot_spacing_s, begin[t], end[t]);
    for (const Pose& c : x->splines[t].control) {
      std::array<double, 7> a;
      PoseToArray(c, a.data());
      x->controls[t].push_back(a);
    }
  }
}

void CopyOut(const Parameters& x, bool splines, BAProblem* p, SplineBAResult* result) {
  for (size_t i = 0; i < p->images.size(); ++i) {
    const auto& q = x.image_q[i];
    const auto& t = x.image_t[i];
    p->images[i].T_world_camera = Pose(Eigen::Quaterniond(q[3], q[0], q[1], q[2]), Eigen::Vector3d(t[0], t[1], t[2]));
  }
  for (size_t k = 0; k < p->points.size(); ++k)
    p->points[k].xyz = Eigen::Vector3d(x.points[k][0], x.points[k][1], x.points[k][2]);
  for (size_t s = 0; s < p->sensors.size(); ++s) {
    p->sensors[s].camera.params.assign(x.intrinsics[s].begin(), x.intrinsics[s].end());
    const auto& q = x.q_body_camera[s];
    p->sensors[s].T_body_camera.q = Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized();
    p->sensors[s].time_offset_s = x.time_offsets[s];
  }
  if (!splines) return;
  result->splines = x.splines;
  for (const auto& g : x.alignments) result->trajectory_alignments.push_back(PoseFromArray(g.data()));
  for (double ls : x.log_scales) result->trajectory_scales.push_back(std::exp(ls));
  for (size_t t = 0; t < p->trajectories.size(); ++t) {
    SE3Spline& spline = result->splines[t];
    if (x.controls[t].empty()) continue;
    for (size_t k = 0; k < spline.control.size(); ++k) spline.control[k] = PoseFromArray(x.controls[t][k].data());
    auto& tr = p->trajectories[t];
    for (size_t i = 0; i < tr.times_s.size(); ++i) tr.T_world_body[i] = spline.Evaluate(tr.times_s[i]);
  }
}

}  // namespace

double MeanReprojectionError(const BAProblem& problem, int* count) {
  double sum = 0;
  int n = 0;
  for (const auto& o : problem.observations) {
    Eigen::Vector2d xy;
    if (!InFront(problem, o, &xy)) continue;
    sum += (xy - o.xy).norm();
    ++n;
  }
  if (count) *count = n;
  return n ? sum / n : 0.0;
}

std::vector<SensorStats> PerSensorStats(const BAProblem& problem) {
  std::vector<SensorStats> stats(problem.sensors.size());
  for (const auto& o : problem.observations) {
    Eigen::Vector2d xy;
    if (!InFront(problem, o, &xy)) continue;
    SensorStats& s = stats[problem.images[o.image].sensor];
    s.mean_reproj_px += (xy - o.xy).norm();
    ++s.observations;
  }
  for (auto& s : stats)
    if (s.observations) s.mean_reproj_px /= s.observations;
  return stats;
}

SplineBAResult RunSplineBA(const SplineBAOptions& options, BAProblem* problem) {
  const auto start = std::chrono::steady_clock::now();
  SplineBAResult result;
  auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  if (const std::string why = options.CheckMessage(); !why.empty()) {
    result.message = "invalid options: " + why;
    return result;
  }
  if (const std::string why = problem->Validate(); !why.empty()) {
    result.message = "invalid problem: " + why;
    return result;
  }
  result.initial_mean_reproj_px = MeanReprojectionError(*problem);
  result.final_mean_reproj_px = result.initial_mean_reproj_px;

  const bool splines = options.use_spline_prior;
  std::vector<std::byte> buffer;
  std::optional<std::pmr::monotonic_buffer_resource> arena;
  std::optional<Parameters> packed;
  {
    Parameters loose;
    CopyIn(*problem, &loose);
    if (splines) FitSplines(*problem, options.knot_spacing_s, &loose);
    // Twice the bound: the arena never falls back to the heap (which would
    // still be correct, only no longer deterministic).
    buffer.resize(2 * PackedBytes(loose));
    arena.emplace(buffer.data(), buffer.size());
    packed.emplace(&*arena);
    Pack(loose, &*packed);
  }
  Parameters& x = *packed;

  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem ceres_problem(problem_options);
  ceres::EigenQuaternionManifold quaternion;
  ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>> se3;
  ceres::CauchyLoss cauchy(options.cauchy_scale_px);

  // (1) Reprojection errors of the observations in front of their camera.
  std::vector<bool> image_observed(problem->images.size(), false);
  for (const auto& o : problem->observations) {
    Eigen::Vector2d xy;
    if (!InFront(*problem, o, &xy)) continue;
    const auto& im = problem->images[o.image];
    ceres_problem.AddResidualBlock(CreateReprojectionError(problem->sensors[im.sensor].camera.model, o.xy), &cauchy,
                                   x.image_q[o.image].data(), x.image_t[o.image].data(), x.points[o.point].data(),
                                   x.intrinsics[im.sensor].data());
    image_observed[o.image] = true;
    ++result.num_observations;
  }
  if (result.num_observations == 0) {
    result.message = "nothing to adjust: no observation in front of its camera";
    result.seconds = elapsed();
    return result;
  }

  // (2) Spline pose errors of the observed images, (3) the weak gauge prior
  // of each used spline to its LiDAR samples.
  std::vector<bool> sensor_in_prior(problem->sensors.size(), false);
  if (splines) {
    const auto w = SqrtInformation(options.prior_sigma_rotation_rad, options.prior_sigma_translation_m);
    for (size_t i = 0; i < problem->images.size(); ++i) {
      const auto& im = problem->images[i];
      if (!image_observed[i] || im.trajectory < 0) continue;
      int s;
      double u;
      const SE3Spline& spline = x.splines[im.trajectory];
      spline.Locate(im.time_s + x.time_offsets[im.sensor], &s, &u);
      // u relative to the segment at time_s (the offset is added inside).
      u = (im.time_s - spline.t0) / spline.dt - s;
      auto& c = x.controls[im.trajectory];
      ceres_problem.AddResidualBlock(
          SplinePoseError::Create(u, spline.dt, problem->sensors[im.sensor].T_body_camera.t, w), nullptr, c[s].data(),
          c[s + 1].data(), c[s + 2].data(), c[s + 3].data(), x.image_q[i].data(), x.image_t[i].data(),
          x.q_body_camera[im.sensor].data(), &x.time_offsets[im.sensor]);
      sensor_in_prior[im.sensor] = true;
      ++result.num_prior_residuals;
    }
    const bool gauge_prior =
        options.trajectory_prior_sigma_rotation_rad > 0 && options.trajectory_prior_sigma_translation_m > 0;
    const auto wg = gauge_prior ? SqrtInformation(options.trajectory_prior_sigma_rotation_rad,
                                                  options.trajectory_prior_sigma_translation_m)
                                : Eigen::Matrix<double, 6, 1>::Zero().eval();
    bool fixed_one = false;
    std::array<double, 7> identity;
    PoseToArray(Pose(), identity.data());
    x.alignments.assign(x.controls.size(), identity);
    x.log_scales.assign(x.controls.size(), 0.0);
    std::vector<double*> log_scales;  // of the trajectories with images
    const auto wa = SqrtInformation(options.alignment_sigma_rotation_rad, options.alignment_sigma_translation_m);
    bool reference_taken = false;
    for (size_t t = 0; t < x.controls.size(); ++t) {
      auto& c = x.controls[t];
      if (c.empty()) continue;
      const auto& tr = problem->trajectories[t];
      // The first trajectory with images is the reference of the alignments.
      double* g = nullptr;
      if (options.align_trajectories && reference_taken) g = x.alignments[t].data();
      reference_taken = true;
      double* ls = options.scale_trajectories && gauge_prior ? &x.log_scales[t] : nullptr;
      // Every control pose needs a residual to be in the problem; controls
      // no image touches are simply not adjusted (and written back as fitted).
      if (gauge_prior) {
        for (size_t i = 0; i < tr.times_s.size(); ++i) {
          int s;
          double u;
          x.splines[t].Locate(tr.times_s[i], &s, &u);
          if (g && ls)
            ceres_problem.AddResidualBlock(ScaledSplineSampleError::CreateAligned(u, tr.T_world_body[i], wg), nullptr,
                                           c[s].data(), c[s + 1].data(), c[s + 2].data(), c[s + 3].data(), g, ls);
          else if (ls)
            ceres_problem.AddResidualBlock(ScaledSplineSampleError::Create(u, tr.T_world_body[i], wg), nullptr,
                                           c[s].data(), c[s + 1].data(), c[s + 2].data(), c[s + 3].data(), ls);
          else if (g)
            ceres_problem.AddResidualBlock(SplineSampleError::CreateAligned(u, tr.T_world_body[i], wg), nullptr,
                                           c[s].data(), c[s + 1].data(), c[s + 2].data(), c[s + 3].data(), g);
          else
            ceres_problem.AddResidualBlock(SplineSampleError::Create(u, tr.T_world_body[i], wg), nullptr,
                                           c[s].data(), c[s + 1].data(), c[s + 2].data(), c[s + 3].data());
          ++result.num_prior_residuals;
        }
        if (g) {
          ceres_problem.AddResidualBlock(ControlPoseError::Create(Pose(), wa), nullptr, g);
          ceres_problem.SetManifold(g, &se3);
          ++result.num_prior_residuals;
        }
        if (ls) {
          ceres_problem.AddResidualBlock(new ScalarSumError(1, 1.0 / options.trajectory_scale_sigma), nullptr, ls);
          log_scales.push_back(ls);
          ++result.num_prior_residuals;
        }
      }
      for (auto& ck : c)
        if (ceres_problem.HasParameterBlock(ck.data())) {
          ceres_problem.SetManifold(ck.data(), &se3);
          if (!gauge_prior && !fixed_one) {
            ceres_problem.SetParameterBlockConstant(ck.data());
            fixed_one = true;
          }
        }
    }
    // Wheeled-base kinematics, once per segment whose controls are adjusted.
    if (options.nonholonomic_sigma_mps > 0)
      for (size_t t = 0; t < x.controls.size(); ++t) {
        auto& c = x.controls[t];
        for (int s = 0; s + 3 < static_cast<int>(c.size()); ++s) {
          bool adjusted = true;
          for (int j = 0; j < 4; ++j) adjusted = adjusted && ceres_problem.HasParameterBlock(c[s + j].data());
          if (!adjusted) continue;
          ceres_problem.AddResidualBlock(
              NonholonomicError::Create(x.splines[t].dt, options.nonholonomic_sigma_mps), nullptr, c[s].data(),
              c[s + 1].data(), c[s + 2].data(), c[s + 3].data());
          ++result.num_prior_residuals;
        }
      }
    // The map keeps the LiDAR's mean scale (as the clock offsets' gauge).
    if (log_scales.size() > 1)
      ceres_problem.AddResidualBlock(new ScalarSumError(static_cast<int>(log_scales.size()), 1e5), nullptr,
                                     log_scales);
  }

  // Manifolds and what is held constant.
  std::unique_ptr<ceres::SubsetManifold> scale_gauge;
  std::vector<std::unique_ptr<LinearSubspaceManifold>> restricted_intrinsics;
  for (size_t i = 0; i < problem->images.size(); ++i)
    if (image_observed[i]) ceres_problem.SetManifold(x.image_q[i].data(), &quaternion);
  if (!splines && options.fix_gauge) {
    const size_t first = std::find(image_observed.begin(), image_observed.end(), true) - image_observed.begin();
    ceres_problem.SetParameterBlockConstant(x.image_q[first].data());
    ceres_problem.SetParameterBlockConstant(x.image_t[first].data());
    const Eigen::Vector3d c0 = problem->images[first].T_world_camera.t;
    size_t far = first;
    double best = 0;
    for (size_t i = 0; i < problem->images.size(); ++i)
      if (image_observed[i] && (problem->images[i].T_world_camera.t - c0).norm() > best) {
        best = (problem->images[i].T_world_camera.t - c0).norm();
        far = i;
      }
    if (far != first) {
      int axis;
      (problem->images[far].T_world_camera.t - c0).cwiseAbs().maxCoeff(&axis);
      scale_gauge = std::make_unique<ceres::SubsetManifold>(3, std::vector<int>{axis});
      ceres_problem.SetManifold(x.image_t[far].data(), scale_gauge.get());
    }
  }
  for (size_t s = 0; s < problem->sensors.size(); ++s) {
    const auto& sensor = problem->sensors[s];
    double* k = x.intrinsics[s].data();
    if (ceres_problem.HasParameterBlock(k)) {
      if (!(options.calibrate_intrinsics && sensor.calibrate_intrinsics)) {
        ceres_problem.SetParameterBlockConstant(k);
      } else {
        const Eigen::MatrixXd basis = IntrinsicsBasis(sensor.camera.model, sensor.camera.params,
                                                      options.fix_aspect_ratio, options.refine_principal_point);
        if (basis.size() > 0) {
          restricted_intrinsics.push_back(std::make_unique<LinearSubspaceManifold>(basis));
          ceres_problem.SetManifold(k, restricted_intrinsics.back().get());
        }
      }
    }
    double* q = x.q_body_camera[s].data();
    if (sensor_in_prior[s]) {
      ceres_problem.SetManifold(q, &quaternion);
      if (!(options.calibrate_rotations && sensor.calibrate_rotation)) ceres_problem.SetParameterBlockConstant(q);
      double* d = &x.time_offsets[s];
      if (options.estimate_time_offsets) {
        ceres_problem.SetParameterLowerBound(d, 0, -options.max_time_offset_s);
        ceres_problem.SetParameterUpperBound(d, 0, options.max_time_offset_s);
        x.time_offsets[s] = std::clamp(x.time_offsets[s], -options.max_time_offset_s, options.max_time_offset_s);
      } else {
        ceres_problem.SetParameterBlockConstant(d);
      }
    }
  }
  if (options.estimate_time_offsets && options.zero_mean_time_offsets) {
    std::vector<double*> offsets;
    for (size_t s = 0; s < problem->sensors.size(); ++s)
      if (sensor_in_prior[s]) offsets.push_back(&x.time_offsets[s]);
    // 1e-5 s per unit of the sum: stiff against the offsets' own information.
    if (offsets.size() >= 2)
      ceres_problem.AddResidualBlock(new ScalarSumError(static_cast<int>(offsets.size()), 1e5), nullptr, offsets);
  }
  if (!options.refine_points)
    for (auto& p : x.points)
      if (ceres_problem.HasParameterBlock(p.data())) ceres_problem.SetParameterBlockConstant(p.data());

  // Schur elimination of the points.
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  std::vector<double*> blocks;
  ceres_problem.GetParameterBlocks(&blocks);
  for (double* b : blocks) ordering->AddElementToGroup(b, 1);
  for (auto& p : x.points)
    if (ceres_problem.HasParameterBlock(p.data()) && !ceres_problem.IsParameterBlockConstant(p.data()))
      ordering->AddElementToGroup(p.data(), 0);
  if (ordering->GroupSize(0) == 0) ordering = nullptr;  // no points to eliminate
  result.num_parameters = ceres_problem.NumParameters();
  for (double* b : blocks)
    result.num_parameters += ceres_problem.IsParameterBlockConstant(b)
                                 ? -ceres_problem.ParameterBlockSize(b)
                                 : ceres_problem.ParameterBlockTangentSize(b) - ceres_problem.ParameterBlockSize(b);

  ceres::Solver::Options solver;
  const bool iterative = options.linear_solver == "iterative_schur" ||
                         (options.linear_solver == "auto" &&
                          static_cast<int>(problem->images.size()) > options.sparse_schur_max_images);
  solver.linear_solver_type = ordering ? (iterative ? ceres::ITERATIVE_SCHUR : ceres::SPARSE_SCHUR)
                                       : ceres::SPARSE_NORMAL_CHOLESKY;
  solver.preconditioner_type = ceres::SCHUR_JACOBI;
  solver.linear_solver_ordering = ordering;
  solver.eta = options.iterative_eta;
  solver.max_num_iterations = options.max_iterations;
  solver.function_tolerance = options.function_tolerance;
  solver.gradient_tolerance = options.gradient_tolerance;
  solver.parameter_tolerance = options.parameter_tolerance;
  solver.num_threads = options.num_threads;
  solver.minimizer_progress_to_stdout = options.verbose;
  solver.logging_type = options.verbose ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &ceres_problem, &summary);

  result.iterations = static_cast<int>(summary.iterations.size()) - 1;
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.converged = summary.termination_type == ceres::CONVERGENCE;
  result.usable = summary.IsSolutionUsable();
  result.message = summary.message;
  if (result.usable) {
    CopyOut(x, splines, problem, &result);
    result.final_mean_reproj_px = MeanReprojectionError(*problem);
  }
  result.seconds = elapsed();
  return result;
}

}  // namespace locforge::sfm

// The spline bundle adjustment of spline_ba.h (paper section 3.2).
#include "spline_ba.h"

#include <ceres/ceres.h>

#include <Eigen/QR>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstddef>
#include <memory>
#include <memory_resource>
#include <optional>
#include <sstream>

#include "cost_functions.h"
#include "schur_lm.h"

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
  if (parallel_schur_tile < 0) return "parallel_schur_tile must be >= 0";
  if (!(parallel_schur_tile_flop_ratio >= 0)) return "parallel_schur_tile_flop_ratio must be >= 0";
  if (!(iterative_eta > 0 && iterative_eta < 1)) return "iterative_eta must be in (0, 1)";
  if (!positive(max_time_offset_s) || max_time_offset_s >= knot_spacing_s)
    return "max_time_offset_s must be in (0, knot_spacing_s)";
  if (linear_solver != "auto" && linear_solver != "sparse_schur" && linear_solver != "iterative_schur" &&
      linear_solver != "dense_schur" && linear_solver != "parallel_schur")
    return "linear_solver must be auto, sparse_schur, iterative_schur, dense_schur or parallel_schur (got '" +
           linear_solver + "')";
  if (sparse_library != "suite_sparse" && sparse_library != "eigen_sparse")
    return "sparse_library must be suite_sparse or eigen_sparse (got '" + sparse_library + "')";
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
  for (size_t k = 0; k < point_summaries.size(); ++k)
    if (point_summaries[k].point < 0 || point_summaries[k].point >= np)
      return "point summary " + std::to_string(k) + ": point index out of range";
  return "";
}

bool InFront(const BAProblem& problem, const BAProblem::Observation& o, Eigen::Vector2d* xy) {
  const BAProblem::Image& im = problem.images[o.image];
  const Eigen::Vector3d p = im.T_world_camera.Inverse() * problem.points[o.point].xyz;
  if (!(p.z() > 0)) return false;
  if (xy) *xy = problem.sensors[im.sensor].camera.Project(p);
  return true;
}

namespace {

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
      : image_pose(memory), points(memory), intrinsics(memory), q_body_camera(memory),
        time_offsets(memory), controls(memory), alignments(memory), log_scales(memory) {}
  std::pmr::vector<std::array<double, 7>> image_pose;  // T_world_camera [qx qy qz qw tx ty tz]
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
  size_t doubles = 7 * x.image_pose.size() + 3 * x.points.size() + 4 * x.q_body_camera.size() +
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
  to->image_pose.assign(from.image_pose.begin(), from.image_pose.end());
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
  for (const auto& im : p.images) PoseToArray(im.T_world_camera, x->image_pose.emplace_back().data());
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
    if (t < p.start_splines.size()) {
      const SE3Spline& start = p.start_splines[t];
      if (start.t0 == x->splines[t].t0 && start.dt == x->splines[t].dt &&
          start.control.size() == x->splines[t].control.size())
        x->splines[t].control = start.control;
    }
    for (const Pose& c : x->splines[t].control) {
      std::array<double, 7> a;
      PoseToArray(c, a.data());
      x->controls[t].push_back(a);
    }
  }
}

void CopyOut(const Parameters& x, bool splines, BAProblem* p, SplineBAResult* result) {
  for (size_t i = 0; i < p->images.size(); ++i) p->images[i].T_world_camera = PoseFromArray(x.image_pose[i].data());
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

namespace {

// The Ceres problem of one adjustment, the manifolds and the loss its blocks
// point to (not owned by the problem), and what the steps learn on the way.
struct Assembly {
  static ceres::Problem::Options ProblemOptions() {
    ceres::Problem::Options o;
    o.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    o.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    return o;
  }
  Assembly(const SplineBAOptions& options, BAProblem* problem, Parameters* x, SplineBAResult* result)
      : options(options),
        problem(*problem),
        x(*x),
        result(*result),
        ceres(ProblemOptions()),
        cauchy(options.cauchy_scale_px),
        image_observed(problem->images.size(), false),
        sensor_in_prior(problem->sensors.size(), false) {}

  const SplineBAOptions& options;
  BAProblem& problem;
  Parameters& x;
  SplineBAResult& result;
  ceres::Problem ceres;
  ceres::EigenQuaternionManifold quaternion;
  ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>> se3;
  ceres::CauchyLoss cauchy;
  std::unique_ptr<ceres::Manifold> scale_gauge;
  std::vector<std::unique_ptr<LinearSubspaceManifold>> restricted_intrinsics;
  std::vector<bool> image_observed;   // by image: has a reprojection residual
  std::vector<bool> sensor_in_prior;  // by sensor: an image of it has a spline pose residual
  std::vector<double*> log_scales;    // of the trajectories with images
};

// The problem's parameters, with the splines fitted to the LiDAR samples when
// used, packed into one arena. Twice the bound: the arena never falls back to
// the heap (which would still be correct, only no longer deterministic).
void PackParameters(const SplineBAOptions& options, const BAProblem& problem, std::vector<std::byte>* buffer,
                    std::optional<std::pmr::monotonic_buffer_resource>* arena, std::optional<Parameters>* packed) {
  Parameters loose;
  CopyIn(problem, &loose);
  if (options.use_spline_prior) FitSplines(problem, options.knot_spacing_s, &loose);
  buffer->resize(2 * PackedBytes(loose));
  arena->emplace(buffer->data(), buffer->size());
  packed->emplace(&**arena);
  Pack(loose, &**packed);
}

// (1) Reprojection errors of the observations in front of their camera.
void AddReprojectionErrors(Assembly& a) {
  for (const auto& o : a.problem.observations) {
    Eigen::Vector2d xy;
    if (!InFront(a.problem, o, &xy)) continue;
    const auto& im = a.problem.images[o.image];
    a.ceres.AddResidualBlock(CreateReprojectionError(a.problem.sensors[im.sensor].camera.model, o.xy), &a.cauchy,
                             a.x.image_pose[o.image].data(), a.x.points[o.point].data(),
                             a.x.intrinsics[im.sensor].data());
    a.image_observed[o.image] = true;
    ++a.result.num_observations;
  }
}

// (2) Spline pose errors of the observed images.
void AddSplinePoseErrors(Assembly& a) {
  Parameters& x = a.x;
  const auto w = SqrtInformation(a.options.prior_sigma_rotation_rad, a.options.prior_sigma_translation_m);
  for (size_t i = 0; i < a.problem.images.size(); ++i) {
    const auto& im = a.problem.images[i];
    if (!a.image_observed[i] || im.trajectory < 0) continue;
    int s;
    double u;
    const SE3Spline& spline = x.splines[im.trajectory];
    spline.Locate(im.time_s + x.time_offsets[im.sensor], &s, &u);
    // u relative to the segment at time_s (the offset is added inside).
    u = (im.time_s - spline.t0) / spline.dt - s;
    auto& c = x.controls[im.trajectory];
    a.ceres.AddResidualBlock(
        SplinePoseError::Create(u, spline.dt, a.problem.sensors[im.sensor].T_body_camera.t, w), nullptr, c[s].data(),
        c[s + 1].data(), c[s + 2].data(), c[s + 3].data(), x.image_pose[i].data(),
        x.q_body_camera[im.sensor].data(), &x.time_offsets[im.sensor]);
    a.sensor_in_prior[im.sensor] = true;
    ++a.result.num_prior_residuals;
  }
}

// Trajectory t's spline to each of its LiDAR samples, weighted wg, through
// its alignment g and log scale ls when given (null: not estimated).
void AddSampleErrors(Assembly& a, size_t t, const Eigen::Matrix<double, 6, 1>& wg, double* g, double* ls) {
  auto& c = a.x.controls[t];
  const auto& tr = a.problem.trajectories[t];
  for (size_t i = 0; i < tr.times_s.size(); ++i) {
    int s;
    double u;
    a.x.splines[t].Locate(tr.times_s[i], &s, &u);
    if (g && ls)
      a.ceres.AddResidualBlock(ScaledSplineSampleError::CreateAligned(u, tr.T_world_body[i], wg), nullptr,
                               c[s].data(), c[s + 1].data(), c[s + 2].data(), c[s + 3].data(), g, ls);
    else if (ls)
      a.ceres.AddResidualBlock(ScaledSplineSampleError::Create(u, tr.T_world_body[i], wg), nullptr, c[s].data(),
                               c[s + 1].data(), c[s + 2].data(), c[s + 3].data(), ls);
    else if (g)
      a.ceres.AddResidualBlock(SplineSampleError::CreateAligned(u, tr.T_world_body[i], wg), nullptr, c[s].data(),
                               c[s + 1].data(), c[s + 2].data(), c[s + 3].data(), g);
    else
      a.ceres.AddResidualBlock(SplineSampleError::Create(u, tr.T_world_body[i], wg), nullptr, c[s].data(),
                               c[s + 1].data(), c[s + 2].data(), c[s + 3].data());
    ++a.result.num_prior_residuals;
  }
}

// The alignment g's prior to the identity and the log scale ls's prior to 0.
void AddAlignmentPriors(Assembly& a, const Eigen::Matrix<double, 6, 1>& wa, double* g, double* ls) {
  if (g) {
    a.ceres.AddResidualBlock(ControlPoseError::Create(Pose(), wa), nullptr, g);
    a.ceres.SetManifold(g, &a.se3);
    ++a.result.num_prior_residuals;
  }
  if (ls) {
    a.ceres.AddResidualBlock(new ScalarSumError(1, 1.0 / a.options.trajectory_scale_sigma), nullptr, ls);
    a.log_scales.push_back(ls);
    ++a.result.num_prior_residuals;
  }
}

// (3) The weak gauge prior of each used spline to its LiDAR samples (through
// its alignment to the first one and its scale when estimated); without it
// one control pose is held.
void AddTrajectoryPriors(Assembly& a) {
  const SplineBAOptions& options = a.options;
  Parameters& x = a.x;
  const bool gauge_prior =
      options.trajectory_prior_sigma_rotation_rad > 0 && options.trajectory_prior_sigma_translation_m > 0;
  const auto wg = gauge_prior ? SqrtInformation(options.trajectory_prior_sigma_rotation_rad,
                                                options.trajectory_prior_sigma_translation_m)
                              : Eigen::Matrix<double, 6, 1>::Zero().eval();
  bool fixed_one = false;
  std::array<double, 7> identity;
  PoseToArray(Pose(), identity.data());
  x.alignments.assign(x.controls.size(), identity);
  for (size_t t = 0; t < std::min(x.alignments.size(), a.problem.start_alignments.size()); ++t)
    PoseToArray(a.problem.start_alignments[t], x.alignments[t].data());
  x.log_scales.assign(x.controls.size(), 0.0);
  const auto wa = SqrtInformation(options.alignment_sigma_rotation_rad, options.alignment_sigma_translation_m);
  bool reference_taken = a.problem.reference_outside;
  for (size_t t = 0; t < x.controls.size(); ++t) {
    auto& c = x.controls[t];
    if (c.empty()) continue;
    // The first trajectory with images is the reference of the alignments.
    double* g = nullptr;
    if (options.align_trajectories && reference_taken) g = x.alignments[t].data();
    reference_taken = true;
    double* ls = options.scale_trajectories && gauge_prior ? &x.log_scales[t] : nullptr;
    // Every control pose needs a residual to be in the problem; controls
    // no image touches are simply not adjusted (and written back as fitted).
    if (gauge_prior) {
      AddSampleErrors(a, t, wg, g, ls);
      AddAlignmentPriors(a, wa, g, ls);
    }
    for (auto& ck : c)
      if (a.ceres.HasParameterBlock(ck.data())) {
        a.ceres.SetManifold(ck.data(), &a.se3);
        if (!gauge_prior && !fixed_one) {
          a.ceres.SetParameterBlockConstant(ck.data());
          fixed_one = true;
        }
      }
  }
}

// Wheeled-base kinematics, once per segment whose controls are adjusted.
void AddNonholonomicErrors(Assembly& a) {
  if (!(a.options.nonholonomic_sigma_mps > 0)) return;
  for (size_t t = 0; t < a.x.controls.size(); ++t) {
    auto& c = a.x.controls[t];
    for (int s = 0; s + 3 < static_cast<int>(c.size()); ++s) {
      bool adjusted = true;
      for (int j = 0; j < 4; ++j) adjusted = adjusted && a.ceres.HasParameterBlock(c[s + j].data());
      if (!adjusted) continue;
      a.ceres.AddResidualBlock(NonholonomicError::Create(a.x.splines[t].dt, a.options.nonholonomic_sigma_mps),
                               nullptr, c[s].data(), c[s + 1].data(), c[s + 2].data(), c[s + 3].data());
      ++a.result.num_prior_residuals;
    }
  }
}

// Without splines: the first observed image held, and the scale by the one
// coordinate of the farthest image's offset from it that varies most.
void HoldImageGauge(Assembly& a) {
  const std::vector<bool>& observed = a.image_observed;
  const auto& images = a.problem.images;
  const size_t first = std::find(observed.begin(), observed.end(), true) - observed.begin();
  a.ceres.SetParameterBlockConstant(a.x.image_pose[first].data());
  const Eigen::Vector3d c0 = images[first].T_world_camera.t;
  size_t far = first;
  double best = 0;
  for (size_t i = 0; i < images.size(); ++i)
    if (observed[i] && (images[i].T_world_camera.t - c0).norm() > best) {
      best = (images[i].T_world_camera.t - c0).norm();
      far = i;
    }
  if (far != first) {
    int axis;
    (images[far].T_world_camera.t - c0).cwiseAbs().maxCoeff(&axis);
    a.scale_gauge = std::make_unique<ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::SubsetManifold>>(
        ceres::EigenQuaternionManifold(), ceres::SubsetManifold(3, std::vector<int>{axis}));
    a.ceres.SetManifold(a.x.image_pose[far].data(), a.scale_gauge.get());
  }
}

// Sensor s's intrinsics: held, or free in the subspace the options allow.
void SetIntrinsics(Assembly& a, size_t s) {
  const auto& sensor = a.problem.sensors[s];
  double* k = a.x.intrinsics[s].data();
  if (!a.ceres.HasParameterBlock(k)) return;
  if (!(a.options.calibrate_intrinsics && sensor.calibrate_intrinsics)) {
    a.ceres.SetParameterBlockConstant(k);
  } else {
    const Eigen::MatrixXd basis = IntrinsicsBasis(sensor.camera.model, sensor.camera.params,
                                                  a.options.fix_aspect_ratio, a.options.refine_principal_point);
    if (basis.size() > 0) {
      a.restricted_intrinsics.push_back(std::make_unique<LinearSubspaceManifold>(basis));
      a.ceres.SetManifold(k, a.restricted_intrinsics.back().get());
    }
  }
}

// Sensor s's rotation to the body and clock offset (when in the spline prior):
// held, or free (the offset within +-max_time_offset_s).
void SetExtrinsics(Assembly& a, size_t s) {
  if (!a.sensor_in_prior[s]) return;
  const SplineBAOptions& options = a.options;
  double* q = a.x.q_body_camera[s].data();
  a.ceres.SetManifold(q, &a.quaternion);
  if (!(options.calibrate_rotations && a.problem.sensors[s].calibrate_rotation)) a.ceres.SetParameterBlockConstant(q);
  double* d = &a.x.time_offsets[s];
  if (options.estimate_time_offsets) {
    a.ceres.SetParameterLowerBound(d, 0, -options.max_time_offset_s);
    a.ceres.SetParameterUpperBound(d, 0, options.max_time_offset_s);
    a.x.time_offsets[s] = std::clamp(a.x.time_offsets[s], -options.max_time_offset_s, options.max_time_offset_s);
  } else {
    a.ceres.SetParameterBlockConstant(d);
  }
}

// The clock offsets' gauge: their sum held at 0 (1e-5 s per unit of the sum:
// stiff against the offsets' own information).
void AddTimeOffsetGauge(Assembly& a) {
  if (!(a.options.estimate_time_offsets && a.options.zero_mean_time_offsets)) return;
  std::vector<double*> offsets;
  for (size_t s = 0; s < a.problem.sensors.size(); ++s)
    if (a.sensor_in_prior[s]) offsets.push_back(&a.x.time_offsets[s]);
  if (offsets.size() >= 2)
    a.ceres.AddResidualBlock(new ScalarSumError(static_cast<int>(offsets.size()), 1e5), nullptr, offsets);
}

// Manifolds and what is held constant.
void SetManifoldsAndConstants(Assembly& a, bool splines) {
  for (size_t i = 0; i < a.problem.images.size(); ++i)
    if (a.image_observed[i]) a.ceres.SetManifold(a.x.image_pose[i].data(), &a.se3);
  if (!splines && a.options.fix_gauge) HoldImageGauge(a);
  for (size_t s = 0; s < a.problem.sensors.size(); ++s) {
    SetIntrinsics(a, s);
    SetExtrinsics(a, s);
  }
  AddTimeOffsetGauge(a);
  if (!a.options.refine_points)
    for (auto& p : a.x.points)
      if (a.ceres.HasParameterBlock(p.data())) a.ceres.SetParameterBlockConstant(p.data());
}

// Schur elimination of the points (null: no point to eliminate).
std::shared_ptr<ceres::ParameterBlockOrdering> SchurOrdering(Assembly& a) {
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  std::vector<double*> blocks;
  a.ceres.GetParameterBlocks(&blocks);
  for (double* b : blocks) ordering->AddElementToGroup(b, 1);
  for (auto& p : a.x.points)
    if (a.ceres.HasParameterBlock(p.data()) && !a.ceres.IsParameterBlockConstant(p.data()))
      ordering->AddElementToGroup(p.data(), 0);
  if (ordering->GroupSize(0) == 0) ordering = nullptr;
  return ordering;
}

// The tangent-space size of the variable blocks.
int FreeParameters(const ceres::Problem& problem) {
  std::vector<double*> blocks;
  problem.GetParameterBlocks(&blocks);
  int n = problem.NumParameters();
  for (double* b : blocks)
    n += problem.IsParameterBlockConstant(b) ? -problem.ParameterBlockSize(b)
                                             : problem.ParameterBlockTangentSize(b) - problem.ParameterBlockSize(b);
  return n;
}

ceres::Solver::Options SolverOptions(const SplineBAOptions& options,
                                     std::shared_ptr<ceres::ParameterBlockOrdering> ordering, size_t images) {
  ceres::Solver::Options solver;
  const bool iterative = options.linear_solver == "iterative_schur" ||
                         (options.linear_solver == "auto" && static_cast<int>(images) > options.sparse_schur_max_images);
  solver.linear_solver_type = !ordering                               ? ceres::SPARSE_NORMAL_CHOLESKY
                              : options.linear_solver == "dense_schur" ? ceres::DENSE_SCHUR
                              : iterative                              ? ceres::ITERATIVE_SCHUR
                                                                       : ceres::SPARSE_SCHUR;
  solver.sparse_linear_algebra_library_type =
      options.sparse_library == "eigen_sparse" ? ceres::EIGEN_SPARSE : ceres::SUITE_SPARSE;
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
  return solver;
}

// Stops the minimiser when the caller's cancellation flag is raised.
class CancellationCallback : public ceres::IterationCallback {
 public:
  explicit CancellationCallback(const std::function<bool()>& cancelled) : cancelled_(cancelled) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return cancelled_() ? ceres::SOLVER_ABORT : ceres::SOLVER_CONTINUE;
  }

 private:
  const std::function<bool()>& cancelled_;
};

// The point summaries of held neighbours (blocked_ba.h), as residuals.
void AddPointSummaries(Assembly& a) {
  for (const auto& summary : a.problem.point_summaries)
    a.ceres.AddResidualBlock(PointSummaryError::Create(summary.x0, summary.S, summary.c), nullptr,
                             a.x.points[summary.point].data());
}

// Builds the problem: residuals (1) to (3) and the kinematics, then the
// manifolds and what is held; false when no observation is in front of its camera.

bool BuildProblem(Assembly& a, bool splines) {
  AddReprojectionErrors(a);
  if (a.result.num_observations == 0) return false;
  AddPointSummaries(a);
  if (splines) {
    AddSplinePoseErrors(a);
    AddTrajectoryPriors(a);
    AddNonholonomicErrors(a);
    // The map keeps the LiDAR's mean scale (as the clock offsets' gauge).
    if (a.log_scales.size() > 1)
      a.ceres.AddResidualBlock(new ScalarSumError(static_cast<int>(a.log_scales.size()), 1e5), nullptr,
                               a.log_scales);
  }
  SetManifoldsAndConstants(a, splines);
  return true;
}

// The solver's summary into the result, and the estimate into the problem when usable.
void ReadBack(const ceres::Solver::Summary& summary, const Parameters& x, bool splines, BAProblem* problem,
              SplineBAResult* result) {
  result->iterations = static_cast<int>(summary.iterations.size()) - 1;
  result->initial_cost = summary.initial_cost;
  result->final_cost = summary.final_cost;
  result->converged = summary.termination_type == ceres::CONVERGENCE;
  result->usable = summary.IsSolutionUsable();
  result->message = summary.message;
  if (result->usable) {
    CopyOut(x, splines, problem, result);
    result->final_mean_reproj_px = MeanReprojectionError(*problem);
  }
}

// The same problem minimised by SolveSchurLM (schur_lm.h) instead of Ceres.
// `ordering` null: no point to eliminate (the whole problem is the reduced system).
void SolveWithSchurLM(Assembly& a, const ceres::ParameterBlockOrdering* ordering) {
  SchurLMOptions lm;
  lm.max_iterations = a.options.max_iterations;
  lm.function_tolerance = a.options.function_tolerance;
  lm.gradient_tolerance = a.options.gradient_tolerance;
  lm.parameter_tolerance = a.options.parameter_tolerance;
  lm.num_threads = a.options.num_threads;
  lm.factorization_tile = a.options.parallel_schur_tile;
  lm.tile_flop_ratio = a.options.parallel_schur_tile_flop_ratio;
  lm.verbose = a.options.verbose;
  lm.cancelled = a.options.cancelled;
  std::vector<double*> points;
  if (ordering) points.assign(ordering->group_to_elements().at(0).begin(), ordering->group_to_elements().at(0).end());
  const SchurLMSummary summary = SolveSchurLM(lm, points, &a.ceres);
  SplineBAResult& result = a.result;
  result.iterations = summary.iterations;
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.converged = summary.converged;
  result.cancelled = summary.cancelled;
  result.usable = summary.usable && !summary.cancelled;
  char seconds[320];
  std::snprintf(seconds, sizeof seconds,
                " (residuals and Jacobians %.2f s, steps %.2f s of which factorisation %.2f s; reduced system %ld "
                "columns, factorised by %s: %.3g values, %.3g flops)",
                summary.evaluate_seconds, summary.step_seconds, summary.factorize_seconds, summary.reduced_columns,
                summary.factorization.c_str(), summary.factor_nonzeros, summary.factor_flops);
  result.message = summary.message + seconds;
  if (result.usable) {
    CopyOut(a.x, a.options.use_spline_prior, &a.problem, &result);
    result.final_mean_reproj_px = MeanReprojectionError(a.problem);
  }
}

}  // namespace

// Build problem -> solve -> read back.
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
  PackParameters(options, *problem, &buffer, &arena, &packed);
  Parameters& x = *packed;
  Assembly a(options, problem, &x, &result);
  if (!BuildProblem(a, splines)) {
    result.message = "nothing to adjust: no observation in front of its camera";
    result.seconds = elapsed();
    return result;
  }
  const std::shared_ptr<ceres::ParameterBlockOrdering> ordering = SchurOrdering(a);
  result.num_parameters = FreeParameters(a.ceres);
  if (options.linear_solver == "parallel_schur") {
    SolveWithSchurLM(a, ordering.get());
    result.seconds = elapsed();
    return result;
  }
  ceres::Solver::Options solver = SolverOptions(options, ordering, problem->images.size());
  std::optional<CancellationCallback> cancellation;
  if (options.cancelled) solver.callbacks.push_back(&cancellation.emplace(options.cancelled));
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &a.ceres, &summary);
  if (cancellation && summary.termination_type == ceres::USER_FAILURE) {
    result.cancelled = true;
    result.message = "cancelled";
    result.seconds = elapsed();
    return result;
  }
  ReadBack(summary, x, splines, problem, &result);
  result.seconds = elapsed();
  return result;
}

}  // namespace locforge::sfm

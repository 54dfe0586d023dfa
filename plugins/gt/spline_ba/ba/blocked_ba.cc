#include "blocked_ba.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numeric>
#include <tuple>

#include <Eigen/Eigenvalues>
#include <ceres/autodiff_cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/product_manifold.h>
#include <ceres/solver.h>

#include "cost_functions.h"
#include "locforge/units.h"

namespace locforge::sfm {

std::string BlockedBAOptions::CheckMessage() const {
  if (blocks < 1) return "blocks must be >= 1";
  if (max_passes < 1) return "max_passes must be >= 1";
  if (!(tolerance_m > 0) || !(tolerance_deg > 0)) return "tolerance_m and tolerance_deg must be > 0";
  return "";
}

std::vector<int> AssignBlocks(const BAProblem& problem, int blocks) {
  std::vector<int> images_of(problem.trajectories.size(), 0);
  for (const auto& im : problem.images)
    if (im.trajectory >= 0) ++images_of[im.trajectory];
  std::vector<int> order(images_of.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return images_of[a] > images_of[b]; });
  std::vector<int> block_of_trajectory(images_of.size(), 0), load(std::max(blocks, 1), 0);
  for (int t : order) {
    const int b = static_cast<int>(std::min_element(load.begin(), load.end()) - load.begin());
    block_of_trajectory[t] = b;
    load[b] += images_of[t];
  }
  std::vector<int> block(problem.images.size(), 0);
  for (size_t i = 0; i < problem.images.size(); ++i)
    if (problem.images[i].trajectory >= 0) block[i] = block_of_trajectory[problem.images[i].trajectory];
  return block;
}

namespace {

// One block's problem and where its images, points and trajectories come from.
struct Block {
  BAProblem problem;
  std::vector<int> image_of, point_of, trajectory_of;  // block index -> full index
};

// What the observations of point p by images outside block b say about p,
// their cost 0.5 sum rho(|r|^2) to second order (Gauss-Newton, the Cauchy
// weight rho' at the current estimate) as 0.5 |S (x - x0) + c|^2 with
// S^T S = H and S^T c = g: the gradient is exact, so the passes' fixed point
// is the whole BA's minimum; only the held images' poses are needed.
BAProblem::PointSummary Summarise(const BAProblem& full, const std::vector<const BAProblem::Observation*>& held,
                                  double cauchy_scale_px) {
  BAProblem::PointSummary summary;
  summary.x0 = full.points[held.front()->point].xyz;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  const ceres::CauchyLoss loss(cauchy_scale_px);
  for (const BAProblem::Observation* o : held) {
    const BAProblem::Image& im = full.images[o->image];
    if (!InFront(full, *o)) continue;  // as RunSplineBA: behind, not used
    std::array<double, 7> pose;
    PoseToArray(im.T_world_camera, pose.data());
    const auto& params = full.sensors[im.sensor].camera.params;
    std::unique_ptr<ceres::CostFunction> f(CreateReprojectionError(full.sensors[im.sensor].camera.model, o->xy));
    const double* parameters[3] = {pose.data(), summary.x0.data(), params.data()};
    Eigen::Vector2d r;
    Eigen::Matrix<double, 2, 3, Eigen::RowMajor> J;
    double* jacobians[3] = {nullptr, J.data(), nullptr};
    if (!f->Evaluate(parameters, r.data(), jacobians)) continue;
    double rho[3];
    loss.Evaluate(r.squaredNorm(), rho);
    H += rho[1] * J.transpose() * J;
    g += rho[1] * J.transpose() * r;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(H);
  const double floor = 1e-12 * std::max(eigen.eigenvalues().maxCoeff(), 0.0);
  for (int k = 0; k < 3; ++k) {
    const double lambda = eigen.eigenvalues()(k);
    if (!(lambda > floor)) continue;  // a direction the held views do not see
    const Eigen::Vector3d v = eigen.eigenvectors().col(k);
    summary.S.row(k) = std::sqrt(lambda) * v.transpose();
    summary.c(k) = v.dot(g) / std::sqrt(lambda);
  }
  return summary;
}

// Block b of `full`: its images (free, tied to their trajectories, whose
// priors are the LiDAR samples of `full`'s trajectories) and every point they observe (free);
// with `coupled`, each point's observations by the other blocks' images as
// one summary (above), those images held at their latest estimate.
// The splines and alignments of the last pass start the block's trajectories.
Block ExtractBlock(const BAProblem& full, const std::vector<int>& block_of_image, int b, int reference_trajectory,
                   const std::vector<SE3Spline>& splines, const std::vector<Pose>& alignments, bool coupled,
                   double cauchy_scale_px) {
  Block k;
  const size_t ni = full.images.size(), np = full.points.size();
  // A point the block can place: seen (in front) twice by its images, or
  // (coupled) once by them and at least once by the others' (a single view
  // leaves its depth free and the block's system singular).
  std::vector<int> own(np, 0), others(np, 0);
  for (const auto& o : full.observations)
    if (InFront(full, o)) ++(block_of_image[o.image] == b ? own : others)[o.point];
  std::vector<char> point_in(np, 0);
  for (size_t p = 0; p < np; ++p) point_in[p] = own[p] >= 2 || (coupled && own[p] >= 1 && others[p] >= 1);
  std::vector<int> trajectory_index(full.trajectories.size(), -1), image_index(ni, -1), point_index(np, -1);
  for (size_t i = 0; i < ni; ++i)
    if (block_of_image[i] == b && full.images[i].trajectory >= 0) trajectory_index[full.images[i].trajectory] = 0;
  for (size_t t = 0; t < trajectory_index.size(); ++t)
    if (trajectory_index[t] == 0) {
      trajectory_index[t] = static_cast<int>(k.trajectory_of.size());
      k.trajectory_of.push_back(static_cast<int>(t));
      k.problem.trajectories.push_back(full.trajectories[t]);
      k.problem.start_splines.push_back(splines[t]);
      k.problem.start_alignments.push_back(alignments[t]);
    }
  k.problem.reference_outside = reference_trajectory < 0 || trajectory_index[reference_trajectory] < 0;
  k.problem.sensors = full.sensors;
  for (size_t i = 0; i < ni; ++i) {
    if (block_of_image[i] != b) continue;
    image_index[i] = static_cast<int>(k.image_of.size());
    k.image_of.push_back(static_cast<int>(i));
    BAProblem::Image im = full.images[i];
    im.trajectory = im.trajectory < 0 ? -1 : trajectory_index[im.trajectory];
    k.problem.images.push_back(im);
  }
  for (size_t p = 0; p < np; ++p) {
    if (!point_in[p]) continue;
    point_index[p] = static_cast<int>(k.point_of.size());
    k.point_of.push_back(static_cast<int>(p));
    k.problem.points.push_back(full.points[p]);
  }
  std::vector<std::vector<const BAProblem::Observation*>> held(coupled ? k.point_of.size() : 0);
  for (const auto& o : full.observations) {
    if (!point_in[o.point]) continue;
    if (image_index[o.image] >= 0)
      k.problem.observations.push_back({image_index[o.image], point_index[o.point], o.xy});
    else if (coupled)
      held[point_index[o.point]].push_back(&o);
  }
  for (size_t p = 0; p < held.size(); ++p)
    if (!held[p].empty()) {
      k.problem.point_summaries.push_back(Summarise(full, held[p], cauchy_scale_px));
      k.problem.point_summaries.back().point = static_cast<int>(p);
    }
  return k;
}

// The block's adjusted images, points, splines and alignments into the
// passes' state (the trajectories' samples stay the LiDAR's: the anchors).
void WriteBack(const Block& k, const SplineBAResult& solved, BAProblem* full, std::vector<SE3Spline>* splines,
               std::vector<Pose>* alignments) {
  for (size_t i = 0; i < k.image_of.size(); ++i) full->images[k.image_of[i]].T_world_camera = k.problem.images[i].T_world_camera;
  for (size_t p = 0; p < k.point_of.size(); ++p) full->points[k.point_of[p]] = k.problem.points[p];
  for (size_t t = 0; t < k.trajectory_of.size(); ++t) {
    if (t < solved.splines.size()) (*splines)[k.trajectory_of[t]] = solved.splines[t];
    if (t < solved.trajectory_alignments.size()) (*alignments)[k.trajectory_of[t]] = solved.trajectory_alignments[t];
  }
}

// Largest camera centre (m) and rotation (deg) change between two states.
std::pair<double, double> LargestChange(const BAProblem& a, const BAProblem& b) {
  double dm = 0, ddeg = 0;
  for (size_t i = 0; i < a.images.size(); ++i) {
    const Pose& p = a.images[i].T_world_camera;
    const Pose& q = b.images[i].T_world_camera;
    dm = std::max(dm, (p.t - q.t).norm());
    ddeg = std::max(ddeg, p.q.angularDistance(q.q) / kDeg);
  }
  return {dm, ddeg};
}

// ------------------------------------------------ the coarse correction
// A common similarity S = (H, exp(log_scale)) of the whole state (images,
// points, splines) leaves every reprojection unchanged, and a block held by
// the others cannot make it: block descent would move along it only as fast
// as the weak LiDAR priors pull. So between passes S is solved for directly,
// on the terms it changes: the LiDAR priors (with the alignments G_t, which
// absorb it otherwise), the spline pose errors (the lever arm t_bc is not
// scaled) and the kinematics (velocities are). Leaving out the last two put
// the blocked result 1.8 mm (a scale of 2.3e-4) from the whole one.

template <typename T>
PoseT<T> MovedBy(const T* h, const T* log_scale, const Pose& pose) {
  const PoseT<T> H = PoseT<T>::FromArray(h);
  PoseT<T> moved = PoseT<T>::Cast(pose);
  moved.t = H.q * (moved.t * exp(log_scale[0])) + H.t;
  moved.q = H.q * moved.q;
  return moved;
}

template <typename T>
std::array<T, 7> MovedArray(const T* h, const T* log_scale, const Pose& pose) {
  const PoseT<T> m = MovedBy(h, log_scale, pose);
  return {m.q.x(), m.q.y(), m.q.z(), m.q.w(), m.t.x(), m.t.y(), m.t.z()};
}

// A LiDAR sample's prior at the moved spline: sqrt_info * Log( M^-1 * G_t^-1 * S * T_wb(t) ).
struct MovedSampleError {
  Pose measured_inverse, spline_pose;
  Eigen::Matrix<double, 6, 1> sqrt_info;
  template <typename T>
  bool operator()(const T* h, const T* log_scale, const T* g, T* residual) const {
    const PoseT<T> moved = MovedBy(h, log_scale, spline_pose);
    const Eigen::Matrix<T, 6, 1> e =
        LogSE3T(PoseT<T>::Cast(measured_inverse) * PoseT<T>::FromArray(g).Inverse() * moved);
    for (int k = 0; k < 6; ++k) residual[k] = T(sqrt_info(k)) * e(k);
    return true;
  }
};

// An image's spline pose error (cost_functions.h) at the moved state.
struct MovedSplinePoseError {
  SplinePoseError inner;
  std::array<Pose, 4> controls;
  Pose image;
  std::array<double, 4> q_bc;
  double time_offset;
  template <typename T>
  bool operator()(const T* h, const T* log_scale, T* residual) const {
    std::array<std::array<T, 7>, 5> a;
    for (int j = 0; j < 5; ++j) a[j] = MovedArray(h, log_scale, j < 4 ? controls[j] : image);
    const T q[4] = {T(q_bc[0]), T(q_bc[1]), T(q_bc[2]), T(q_bc[3])};
    const T offset = T(time_offset);
    return inner(a[0].data(), a[1].data(), a[2].data(), a[3].data(), a[4].data(), q, &offset, residual);
  }
};

// A segment's kinematics (cost_functions.h) at the moved state.
struct MovedNonholonomicError {
  NonholonomicError inner;
  std::array<Pose, 4> controls;
  template <typename T>
  bool operator()(const T* h, const T* log_scale, T* residual) const {
    std::array<std::array<T, 7>, 4> a;
    for (int j = 0; j < 4; ++j) a[j] = MovedArray(h, log_scale, controls[j]);
    return inner(a[0].data(), a[1].data(), a[2].data(), a[3].data(), residual);
  }
};

std::array<Pose, 4> SegmentControls(const SE3Spline& spline, int s) {
  return {spline.control[s], spline.control[s + 1], spline.control[s + 2], spline.control[s + 3]};
}

// The unknowns of the correction: S, and each trajectory's alignment (held
// at the identity for the reference trajectory and without align_trajectories).
struct Correction {
  std::array<double, 7> h;
  double log_scale = 0;
  std::vector<std::array<double, 7>> g;
  ceres::Problem problem;
};

void AddMovedPriors(const SplineBAOptions& options, const std::vector<BAProblem::Trajectory>& lidar,
                    const std::vector<SE3Spline>& splines, int reference, Correction* c) {
  const auto w = SqrtInformation(options.trajectory_prior_sigma_rotation_rad, options.trajectory_prior_sigma_translation_m);
  const auto wa = SqrtInformation(options.alignment_sigma_rotation_rad, options.alignment_sigma_translation_m);
  for (size_t t = 0; t < splines.size(); ++t) {
    if (splines[t].control.empty()) continue;
    for (size_t i = 0; i < lidar[t].times_s.size(); ++i)
      c->problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<MovedSampleError, 6, 7, 1, 7>(new MovedSampleError{
              lidar[t].T_world_body[i].Inverse(), splines[t].Evaluate(lidar[t].times_s[i]), w}),
          nullptr, c->h.data(), &c->log_scale, c->g[t].data());
    c->problem.SetManifold(c->g[t].data(),
                           new ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>>);
    if (!options.align_trajectories || static_cast<int>(t) == reference) {
      c->problem.SetParameterBlockConstant(c->g[t].data());
    } else {
      c->problem.AddResidualBlock(ControlPoseError::Create(Pose(), wa), nullptr, c->g[t].data());
    }
  }
}

void AddMovedKinematics(const SplineBAOptions& options, const BAProblem& work, const std::vector<SE3Spline>& splines,
                        Correction* c) {
  const auto w = SqrtInformation(options.prior_sigma_rotation_rad, options.prior_sigma_translation_m);
  for (const auto& im : work.images) {
    if (im.trajectory < 0 || splines[im.trajectory].control.empty()) continue;
    const SE3Spline& spline = splines[im.trajectory];
    const auto& sensor = work.sensors[im.sensor];
    int s;
    double u;
    spline.Locate(im.time_s + sensor.time_offset_s, &s, &u);
    u = (im.time_s - spline.t0) / spline.dt - s;  // as in RunSplineBA: the offset is added inside
    const Eigen::Quaterniond& q = sensor.T_body_camera.q;
    c->problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<MovedSplinePoseError, 6, 7, 1>(new MovedSplinePoseError{
            SplinePoseError(u, spline.dt, sensor.T_body_camera.t, w), SegmentControls(spline, s), im.T_world_camera,
            {q.x(), q.y(), q.z(), q.w()}, sensor.time_offset_s}),
        nullptr, c->h.data(), &c->log_scale);
  }
  if (!(options.nonholonomic_sigma_mps > 0)) return;
  for (const SE3Spline& spline : splines)
    for (int s = 0; s < spline.NumSegments(); ++s)
      c->problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<MovedNonholonomicError, 1, 7, 1>(new MovedNonholonomicError{
              NonholonomicError(spline.dt, options.nonholonomic_sigma_mps), SegmentControls(spline, s)}),
          nullptr, c->h.data(), &c->log_scale);
}

// Solves for S (and the alignments) and applies S to the whole state.
void CorrectCommonMotion(const SplineBAOptions& options, int reference, std::vector<SE3Spline>* splines, std::vector<Pose>* alignments,
                         BAProblem* work) {
  if (!(options.trajectory_prior_sigma_rotation_rad > 0 && options.trajectory_prior_sigma_translation_m > 0)) return;
  Correction c;
  PoseToArray(Pose(), c.h.data());
  c.g.resize(splines->size());
  for (size_t t = 0; t < splines->size(); ++t) PoseToArray((*alignments)[t], c.g[t].data());
  AddMovedPriors(options, work->trajectories, *splines, reference, &c);
  if (c.problem.NumResidualBlocks() == 0) return;
  AddMovedKinematics(options, *work, *splines, &c);
  c.problem.SetManifold(c.h.data(),
                        new ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>>);
  ceres::Solver::Options solver;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &c.problem, &summary);
  if (!summary.IsSolutionUsable()) return;
  const Pose H = PoseFromArray(c.h.data());
  const double k = std::exp(c.log_scale);
  const auto move = [&](const Pose& T) { return Pose(H.q * T.q, H.q * (k * T.t) + H.t); };
  for (auto& im : work->images) im.T_world_camera = move(im.T_world_camera);
  for (auto& p : work->points) p.xyz = H.q * (k * p.xyz) + H.t;
  for (auto& spline : *splines)
    for (Pose& control : spline.control) control = move(control);
  for (size_t t = 0; t < splines->size(); ++t)
    if (!(*splines)[t].control.empty()) (*alignments)[t] = PoseFromArray(c.g[t].data());
}

int ReferenceTrajectory(const BAProblem& problem) {
  int reference = -1;
  for (const auto& im : problem.images)
    if (im.trajectory >= 0 && (reference < 0 || im.trajectory < reference)) reference = im.trajectory;
  return reference;
}

// What the passes carry: the state (its trajectories keep the LiDAR samples,
// the priors' anchors, until the end) and the blocks.
struct Passes {
  BAProblem work;
  std::vector<int> block_of_image;
  int blocks = 0;
  int reference = -1;
  SplineBAOptions in_block;
  std::vector<Pose> alignments;
  std::string log;  // the pass's blocks, for BlockedBAOptions::progress
};

// One pass: every block in turn (the first pass without the neighbours'
// summaries: each block alone, a start near its own optimum), then the
// correction. False (message) when a solve is not usable.
bool RunPass(const SplineBAOptions& options, int pass, Passes* s, BlockedBAResult* result) {
  result->block_images.assign(s->blocks, 0);
  result->block_observations.assign(s->blocks, 0);
  result->block_summaries.assign(s->blocks, 0);
  for (int b = 0; b < s->blocks; ++b) {
    Block k = ExtractBlock(s->work, s->block_of_image, b, s->reference, result->splines, s->alignments,
                           /*coupled=*/pass > 1, options.cauchy_scale_px);
    const SplineBAResult solved = RunSplineBA(s->in_block, &k.problem);
    if (!solved.usable) {
      result->cancelled = solved.cancelled;
      result->message = "pass " + std::to_string(pass) + ", block " + std::to_string(b) + ": " + solved.message;
      return false;
    }
    WriteBack(k, solved, &s->work, &result->splines, &s->alignments);
    char line[64];
    std::snprintf(line, sizeof line, " block %d: %d iterations, %.1f s;", b, solved.iterations, solved.seconds);
    s->log += line;
    result->block_observations[b] = static_cast<int>(k.problem.observations.size());
    result->block_images[b] = static_cast<int>(k.problem.images.size());
    result->block_summaries[b] = static_cast<int>(k.problem.point_summaries.size());
  }
  if (pass > 1) CorrectCommonMotion(options, s->reference, &result->splines, &s->alignments, &s->work);
  return true;
}

}  // namespace

// Passes of (every block, the correction) until the cameras stop moving.
BlockedBAResult RunBlockedSplineBA(const SplineBAOptions& options, const BlockedBAOptions& blocked,
                                   BAProblem* problem) {
  const auto start = std::chrono::steady_clock::now();
  BlockedBAResult result;
  std::string why = options.CheckMessage();
  if (why.empty()) why = blocked.CheckMessage();
  if (why.empty() && !options.use_spline_prior) why = "a blocked BA needs the spline prior (use_spline_prior)";
  if (why.empty() && options.scale_trajectories) why = "scale_trajectories ties every trajectory: not blocked";
  if (why.empty() && (options.calibrate_intrinsics || options.calibrate_rotations || options.estimate_time_offsets))
    why = "the calibration (intrinsics, camera rotations, clock offsets) is shared by every block: hold it "
          "(calibrate it in whole rounds first)";
  if (why.empty()) why = problem->Validate();
  if (!why.empty()) {
    result.message = "refused: " + why;
    return result;
  }
  Passes s{*problem, AssignBlocks(*problem, blocked.blocks), 0, ReferenceTrajectory(*problem),
           options, std::vector<Pose>(problem->trajectories.size()), ""};
  s.blocks = s.block_of_image.empty() ? 0 : *std::max_element(s.block_of_image.begin(), s.block_of_image.end()) + 1;
  // A block starts near its optimum after the first passes: Ceres' relative
  // cost tolerance would stop it at once while the blocks still pull apart.
  s.in_block.function_tolerance = std::min(s.in_block.function_tolerance, 1e-10);
  result.splines.resize(s.work.trajectories.size());
  if (s.work.start_splines.size() == s.work.trajectories.size()) result.splines = s.work.start_splines;
  if (s.work.start_alignments.size() == s.alignments.size()) s.alignments = s.work.start_alignments;
  for (int pass = 1; pass <= blocked.max_passes; ++pass) {
    const BAProblem before = s.work;
    s.log.clear();
    if (!RunPass(options, pass, &s, &result)) return result;
    std::tie(result.last_change_m, result.last_change_deg) = LargestChange(before, s.work);
    result.passes = pass;
    if (blocked.progress) {
      char change[96];
      std::snprintf(change, sizeof change, " largest camera change %.4f mm / %.5f deg", 1000 * result.last_change_m,
                    result.last_change_deg);
      blocked.progress("blocked BA pass " + std::to_string(pass) + ":" + s.log + change);
    }
    if (result.last_change_m < blocked.tolerance_m && result.last_change_deg < blocked.tolerance_deg) {
      result.converged = true;
      break;
    }
  }
  // As RunSplineBA: the trajectories become the adjusted splines' samples.
  for (size_t t = 0; t < s.work.trajectories.size(); ++t)
    if (!result.splines[t].control.empty())
      for (size_t i = 0; i < s.work.trajectories[t].times_s.size(); ++i)
        s.work.trajectories[t].T_world_body[i] = result.splines[t].Evaluate(s.work.trajectories[t].times_s[i]);
  *problem = std::move(s.work);
  result.trajectory_alignments = s.alignments;
  result.usable = true;
  result.message = std::to_string(s.blocks) + " blocks, " + std::to_string(result.passes) + " passes" +
                   (result.converged ? "" : " (not converged)");
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace locforge::sfm

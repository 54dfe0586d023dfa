// SolveSchurLM (schur_lm.h) on the synthetic spline-BA scene with a known
// answer (synthetic.h), against Ceres' SPARSE_SCHUR on the same problem, at
// several thread counts; and the problems it refuses.
#include "schur_lm.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>

#include "spline_ba.h"
#include "synthetic.h"

namespace locforge::sfm {
namespace {

const SyntheticScene& Scene() {
  static const SyntheticScene scene = MakeSyntheticScene(TestSceneOptions());
  return scene;
}

// The synthetic scene's settings, with every calibration block free and
// clock offsets estimated (bounded blocks).
// tile: parallel_schur's factorisation, always by tiles of this size (the
// scene's system is too sparse for the default rule to pick them), 0: CHOLMOD.
SplineBAOptions Options(const std::string& solver, int threads, int tile) {
  SplineBAOptions options = SyntheticSceneBAOptions();
  options.num_threads = threads;
  options.parallel_schur_tile = tile;
  options.parallel_schur_tile_flop_ratio = 1e9;
  options.align_trajectories = true;
  options.estimate_time_offsets = true;
  options.linear_solver = solver;
  return options;
}

struct Adjusted {
  BAProblem problem;
  SplineBAResult result;
  SceneErrors errors;
};

Adjusted Solve(const std::string& solver, int threads, bool refine_points = true, int tile = 0) {
  Adjusted run;
  run.problem = Scene().initial;
  SplineBAOptions options = Options(solver, threads, tile);
  options.refine_points = refine_points;
  run.result = RunSplineBA(options, &run.problem);
  run.errors = CompareToTruth(run.problem, Scene().truth);
  std::printf("  %-15s tile %3d, %d thread(s): cost %.4f -> %.4f, %d it, %.3f cm / %.4f deg, focal %.4f %%, %.2f s (%s)\n",
              solver.c_str(), tile, threads, run.result.initial_cost, run.result.final_cost, run.result.iterations,
              100 * run.errors.position_rms_m, run.errors.rotation_rms_deg, 100 * run.errors.focal_max_rel,
              run.result.seconds, run.result.message.c_str());
  return run;
}

// Largest camera-centre and rotation difference between two solutions.
std::pair<double, double> MaxPoseDifference(const BAProblem& a, const BAProblem& b) {
  double dt = 0, dr = 0;
  for (size_t i = 0; i < a.images.size(); ++i) {
    const Pose& p = a.images[i].T_world_camera;
    const Pose& q = b.images[i].T_world_camera;
    dt = std::max(dt, (p.t - q.t).norm());
    dr = std::max(dr, p.q.angularDistance(q.q) * 180 / M_PI);
  }
  return {dt, dr};
}

// Both factorisations (tiles, CHOLMOD) against Ceres.
TEST(SchurLM, SameMinimumAsCeresSparseSchur) {
  const Adjusted ceres = Solve("sparse_schur", 2);
  ASSERT_TRUE(ceres.result.usable);
  for (int tile : {SplineBAOptions().parallel_schur_tile, 0}) {
    const Adjusted ours = Solve("parallel_schur", 2, true, tile);
    ASSERT_TRUE(ours.result.usable) << ours.result.message;
    EXPECT_TRUE(ours.result.converged) << ours.result.message;
    // Both start from the same cost and end at the same minimum: costs within
    // 0.05 %, and no farther from the truth.
    EXPECT_NEAR(ours.result.initial_cost, ceres.result.initial_cost, 1e-12 * ceres.result.initial_cost);  // summed in another order
    EXPECT_NEAR(ours.result.final_cost, ceres.result.final_cost, 5e-4 * ceres.result.final_cost);
    EXPECT_LT(ours.errors.position_rms_m, 1.1 * ceres.errors.position_rms_m + 1e-4);
    EXPECT_LT(ours.errors.rotation_rms_deg, 1.1 * ceres.errors.rotation_rms_deg + 1e-3);
    EXPECT_LT(ours.errors.focal_max_rel, 1.1 * ceres.errors.focal_max_rel + 1e-4);
    const auto [dt, dr] = MaxPoseDifference(ours.problem, ceres.problem);
    std::printf("  parallel_schur (tile %d) vs sparse_schur: %.3f mm / %.5f deg max\n", tile, 1000 * dt, dr);
    EXPECT_LT(dt, 0.01);  // the scene's flat directions (its blocked-BA study) allow millimetres, not centimetres
    EXPECT_LT(dr, 0.05);
  }
}

// Tiles of 128 (the default), of 48 (many tiles, so threads share the
// factorisation), and CHOLMOD with the retries speculated on a second thread.
TEST(SchurLM, SameBitsAtAnyThreadCount) {
  for (int tile : {SplineBAOptions().parallel_schur_tile, 48, 0}) {
    const Adjusted one = Solve("parallel_schur", 1, true, tile);
    for (int threads : {2, 3}) {
      const Adjusted more = Solve("parallel_schur", threads, true, tile);
      ASSERT_EQ(more.result.iterations, one.result.iterations);
      EXPECT_EQ(more.result.final_cost, one.result.final_cost);
      for (size_t i = 0; i < one.problem.images.size(); ++i) {
        const Pose& a = one.problem.images[i].T_world_camera;
        const Pose& b = more.problem.images[i].T_world_camera;
        ASSERT_EQ(std::memcmp(a.t.data(), b.t.data(), 3 * sizeof(double)), 0) << "tile " << tile << " image " << i;
        ASSERT_EQ(std::memcmp(a.q.coeffs().data(), b.q.coeffs().data(), 4 * sizeof(double)), 0) << "tile " << tile << " image " << i;
      }
      for (size_t s = 0; s < one.problem.sensors.size(); ++s)
        EXPECT_EQ(one.problem.sensors[s].camera.params, more.problem.sensors[s].camera.params);
    }
  }
}

// Points held: nothing to eliminate, the reduced system is the whole problem.
TEST(SchurLM, HeldPointsLeaveNothingToEliminate) {
  const Adjusted ceres = Solve("sparse_schur", 2, false);
  const Adjusted ours = Solve("parallel_schur", 2, false);
  ASSERT_TRUE(ours.result.usable) << ours.result.message;
  // Ceres (SPARSE_NORMAL_CHOLESKY here) stops at 46954.7 after 11 iterations, ours at 46914.8 after 62.
  EXPECT_LT(ours.result.final_cost, (1 + 5e-4) * ceres.result.final_cost);
  EXPECT_LT(ours.result.final_cost, 0.5 * ours.result.initial_cost);
}

// A curve fit (y = exp(m x + c), known m, c) with a Cauchy loss: no point to
// eliminate, so the reduced system is the whole problem.
struct ExpResidual {
  ExpResidual(double x, double y) : x(x), y(y) {}
  template <typename T>
  bool operator()(const T* mc, T* r) const {
    r[0] = T(y) - exp(mc[0] * x + mc[1]);
    return true;
  }
  double x, y;
};

TEST(SchurLM, FitsACurveWithoutPoints) {
  double mc[2] = {0, 0};
  ceres::Problem problem;
  for (int i = 0; i < 50; ++i) {
    const double x = i / 10.0;
    const double y = std::exp(0.3 * x + 0.1) * (1 + 0.001 * std::sin(7.0 * i));
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<ExpResidual, 1, 2>(new ExpResidual(x, y)),
                             new ceres::CauchyLoss(0.5), mc);
  }
  SchurLMOptions options;
  options.max_iterations = 100;
  const SchurLMSummary summary = SolveSchurLM(options, {}, &problem);
  EXPECT_TRUE(summary.converged) << summary.message;
  EXPECT_NEAR(mc[0], 0.3, 1e-3);
  EXPECT_NEAR(mc[1], 0.1, 1e-3);
}

// A raised cancellation flag stops the solve before its next step; RunSplineBA
// then reports it and writes nothing back.
TEST(SchurLM, StopsWhenCancelled) {
  BAProblem problem = Scene().initial;
  SplineBAOptions options = Options("parallel_schur", 2, SplineBAOptions().parallel_schur_tile);
  int polls = 0;
  options.cancelled = [&polls] { return ++polls > 3; };
  const SplineBAResult result = RunSplineBA(options, &problem);
  EXPECT_TRUE(result.cancelled) << result.message;
  EXPECT_FALSE(result.usable);
  EXPECT_EQ(polls, 4);
  EXPECT_EQ(problem.images[0].T_world_camera.t, Scene().initial.images[0].T_world_camera.t);
}

struct Difference {
  template <typename T>
  bool operator()(const T* p, const T* q, T* r) const {
    for (int i = 0; i < 3; ++i) r[i] = p[i] - q[i];
    return true;
  }
};

TEST(SchurLM, RefusesWhatItCannotEliminate) {
  double a[3] = {1, 2, 3}, b[3] = {0, 0, 0};
  ceres::Problem problem;
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Difference, 3, 3, 3>(new Difference), nullptr, a, b);
  const SchurLMSummary summary = SolveSchurLM(SchurLMOptions(), {a, b}, &problem);
  EXPECT_FALSE(summary.usable);
  EXPECT_NE(summary.message.find("two eliminated blocks"), std::string::npos) << summary.message;
  EXPECT_EQ(a[0], 1);  // unchanged
  SchurLMOptions bad;
  bad.num_threads = 0;
  EXPECT_NE(SolveSchurLM(bad, {}, &problem).message.find("num_threads"), std::string::npos);
}

}  // namespace
}  // namespace locforge::sfm

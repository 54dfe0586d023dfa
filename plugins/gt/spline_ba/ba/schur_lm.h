// A Levenberg-Marquardt minimiser for a bundle adjustment held in a
// ceres::Problem, whose reduced camera system is assembled by every thread
// at once without a lock: each thread owns whole block rows of it.
//
// Why not Ceres' SPARSE_SCHUR (issue 40, docs/results/cost-model.md): Ceres
// 2.1 locks the reduced matrix's cells while it eliminates points and then
// rebuilds and sorts the whole matrix on one thread every iteration, which
// caps a second thread near 1.6x on the demo's `gt` node.
//
// The method: the points (the blocks in `eliminate`) are eliminated through
// the Schur complement of the normal equations (Triggs et al., "Bundle
// adjustment - a modern synthesis", 2000, section 6.1):
//   S = A - W^T E^-1 W,  S dc = bc - W^T E^-1 bp,  dp = E^-1 (bp - W dc),
// with E block-diagonal (one 3x3 block per point). S keeps one sparsity
// pattern for the whole solve; CHOLMOD analyses it once (its fill-reducing
// ordering), and every step factorises it: in dense tiles on every thread
// (tiled_cholesky.h) when S is dense enough, else by CHOLMOD. The trust
// region, the Jacobi scaling, the robust-loss correction and the stopping
// rules are those of Ceres' LEVENBERG_MARQUARDT with its default options, so
// both minimise the same cost the same way; their results agree to the
// problem's conditioning, not bit for bit.
// Differences: at a parameter bound a coordinate the descent pushes out is
// held for the step and a step crossing a bound is shortened to it (Ceres
// runs a projected line search instead), and the gradient test uses the
// gradient's max norm.
//
// With CHOLMOD (single-threaded on Debian's ATLAS) and two threads or more,
// the step at the next smaller trust region is computed beside the current
// one (its reduced system assembled with it, its factorisation on the second
// thread): a rejected step then costs no factorisation of its own. Every sum
// is taken in an order that does not depend on the threads, and the choice of
// factorisation does not either, so the result is the same bits at any thread
// count (test SchurLM.SameBitsAtAnyThreadCount).
#ifndef LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_SCHUR_LM_H_
#define LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_SCHUR_LM_H_

#include <functional>
#include <string>
#include <vector>

namespace ceres {
class Problem;
}

namespace locforge::sfm {

struct SchurLMOptions {
  int max_iterations = 50;            // steps tried, accepted or not (as Ceres counts)
  double function_tolerance = 1e-6;   // |cost change| <= this * cost: converged
  double gradient_tolerance = 1e-10;  // max |gradient| <= this: converged
  double parameter_tolerance = 1e-8;  // |step| <= this * (|x| + this): converged
  double initial_trust_region_radius = 1e4;  // Ceres' defaults from here on
  double max_trust_region_radius = 1e16;
  double min_trust_region_radius = 1e-32;
  double min_relative_decrease = 1e-3;  // a step is accepted above this ratio of actual to model decrease
  double min_lm_diagonal = 1e-6;
  double max_lm_diagonal = 1e32;
  int num_threads = 1;
  // The reduced system's factorisation: > 0 TiledCholesky (tiled_cholesky.h)
  // with tiles of this size, factorised on every thread, where it costs at
  // most tile_flop_ratio times CHOLMOD's operations (a dense enough system);
  // else, and with 0, CHOLMOD (on the machine's BLAS).
  int factorization_tile = 128;
  double tile_flop_ratio = 2;
  bool verbose = false;  // one line per step to stdout
  // Polled before every step: true stops the solve (summary.cancelled).
  std::function<bool()> cancelled;

  bool Check() const { return CheckMessage().empty(); }
  std::string CheckMessage() const;
};

struct SchurLMSummary {
  bool converged = false;  // a tolerance was met (not the iteration limit)
  bool usable = false;     // the parameters hold the best point found
  bool cancelled = false;
  int iterations = 0;        // steps tried
  int successful_steps = 0;  // steps accepted
  double initial_cost = 0, final_cost = 0;  // 0.5 * sum of robustified squared residuals (Ceres' cost)
  std::string message;
  // The reduced system: its columns, how it was factorised ("CHOLMOD" or
  // "tiles of N"), the values of its Cholesky factor (CHOLMOD's nonzeros
  // after its fill-reducing ordering, or the tiles' entries) and the
  // operations of one factorisation.
  long reduced_columns = 0;
  std::string factorization;
  double factor_nonzeros = 0, factor_flops = 0;
  // Wall seconds: residuals and Jacobians; the steps (the points' blocks,
  // the reduced system's assembly, its factorisation and solve, the back
  // substitution), of which the factorisation and solve alone.
  double evaluate_seconds = 0, step_seconds = 0, factorize_seconds = 0, total_seconds = 0;
};

// Minimises the problem's cost over its free parameter blocks; the blocks in
// `eliminate` (3 free coordinates each, no manifold, no bounds, no residual
// with two of them) are eliminated. The problem's parameters hold the result
// when summary.usable; a problem outside that shape gets a message and is
// not changed.
SchurLMSummary SolveSchurLM(const SchurLMOptions& options, const std::vector<double*>& eliminate,
                            ceres::Problem* problem);

}  // namespace locforge::sfm

#endif  // LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_SCHUR_LM_H_

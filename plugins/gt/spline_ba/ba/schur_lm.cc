#include "schur_lm.h"

#include "parallel_for.h"
#include "tiled_cholesky.h"

#include <ceres/ceres.h>
#include <cholmod.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <thread>
#include <unordered_map>

namespace locforge::sfm {

std::string SchurLMOptions::CheckMessage() const {
  if (max_iterations < 0) return "max_iterations must be >= 0";
  if (!(function_tolerance >= 0) || !(gradient_tolerance >= 0) || !(parameter_tolerance >= 0))
    return "tolerances must be >= 0";
  if (!(initial_trust_region_radius > 0) || !(max_trust_region_radius >= initial_trust_region_radius))
    return "need 0 < initial_trust_region_radius <= max_trust_region_radius";
  if (!(min_lm_diagonal > 0) || !(max_lm_diagonal >= min_lm_diagonal))
    return "need 0 < min_lm_diagonal <= max_lm_diagonal";
  if (num_threads < 1) return "num_threads must be >= 1";
  if (factorization_tile < 0) return "factorization_tile must be >= 0";
  if (!(tile_flop_ratio >= 0)) return "tile_flop_ratio must be >= 0";
  return "";
}

namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// The largest tangent size of a parameter block (bundle adjustment blocks
// have at most 12: OpenCV's full model).
constexpr int kMaxTangent = 16;

// out (p x q) += X^T Y for X (n x p) and Y (n x q), all row-major.
void AddTransposeProduct(const double* X, int p, const double* Y, int q, int n, double* out) {
  for (int i = 0; i < n; ++i)
    for (int a = 0; a < p; ++a) {
      const double x = X[i * p + a];
      for (int b = 0; b < q; ++b) out[a * q + b] += x * Y[i * q + b];
    }
}

using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using MapRM = Eigen::Map<RowMajor>;
using ConstMapRM = Eigen::Map<const RowMajor>;

struct Block {
  double* values = nullptr;
  int size = 0, tangent = 0;
  const ceres::Manifold* manifold = nullptr;
  bool constant = false;
  int point = -1;          // index among the eliminated blocks
  int reduced = -1;        // index among the reduced blocks
  int offset = -1;         // first coordinate in the tangent vector (reduced blocks first, then points)
  int plus_jacobian = -1;  // offset of its ambient x tangent Plus Jacobian (manifolds only)
  int saved = -1;          // offset of its values in Solver::saved_ (free blocks only)
  std::vector<double> lower, upper;  // empty: unbounded
};

struct Residual {
  const ceres::CostFunction* cost = nullptr;
  const ceres::LossFunction* loss = nullptr;
  int size = 0;
  int point = -1;               // its eliminated block (index among points), or -1
  int values = 0;               // offset of its residuals
  std::vector<int> blocks;      // its parameter blocks (indices into Solver::blocks_)
  std::vector<int> jacobian;    // per parameter: offset of its tangent Jacobian (row-major), -1 if constant
  std::vector<int> point_slot;  // per parameter: its slot in the point's reduced blocks, -1 if none
};

// The reduced system damped for one trust-region radius, and the step it
// gives. The reduced matrix is CHOLMOD's lower triangle by columns: CHOLMOD's
// column i is our scalar row i of the upper block triangle (in a diagonal
// block the entries left of the diagonal are stored, and CHOLMOD ignores them).
struct Damped {
  Damped() = default;
  Damped(const Damped&) = delete;
  Damped& operator=(const Damped&) = delete;
  ~Damped() {
    if (factor) cholmod_l_free_factor(&factor, &common);
    if (matrix) cholmod_l_free_sparse(&matrix, &common);
    if (started) cholmod_l_finish(&common);
  }
  double radius = 0;
  cholmod_common common{};  // one per system: two may be factorised at once
  bool started = false;
  cholmod_sparse* matrix = nullptr;
  cholmod_factor* factor = nullptr;           // CHOLMOD's ordering, and its factor when not tiled
  std::unique_ptr<TiledCholesky> tiled;       // the factorisation when tiles were chosen (Solver::Analyze)
  double* values = nullptr;  // matrix->x
  std::vector<double> e, e_inverse;  // by point: e = E^-1 bp, E^-1 (3 x 3)
  std::vector<double> rhs, step;     // the reduced right-hand side; the whole step (scaled coordinates)
  bool solved = false;               // false: the damped system is not positive definite (a rejected step)
  double model_change = 0;           // the decrease of the linearised cost the step predicts
  std::string failed;                // an error that ends the solve
};

class Solver {
 public:
  Solver(const SchurLMOptions& options, ceres::Problem* problem) : options_(options), problem_(*problem) {}

  SchurLMSummary Run(const std::vector<double*>& eliminate);

 private:
  std::string Structure(const std::vector<double*>& eliminate);
  void Order(const std::vector<int>& uses);
  void Storage();
  void Pattern();
  void Analyze(SuiteSparse_long n, SuiteSparse_long* rowind);
  bool Linearize(bool first);
  void Robustify(int k);
  void JacobiScaling();
  bool Cost(double* cost);
  std::string Prepare(const std::vector<double*>& eliminate, double* cost);
  std::string Iterate(double cost);
  bool TryStep(const Damped& d, double cost, double* new_cost, double* rho, std::string* stop);
  void Steps(Damped* first, Damped* second);
  void AssembleRow(Damped& d, int row, bool write_gradient);
  void HoldActiveBounds(Damped& d);
  void Factorize(Damped& d);
  void Finish(Damped& d);
  void Save();
  void Restore();
  void Candidate(const std::vector<double>& step);
  double StepNorm(const std::vector<double>& step) const;
  double StateNorm() const;

  double& S(Damped& d, int row, int a, int col_pos, int b) {
    return d.values[colptr_[reduced_offset(row) + a] + col_pos + b];
  }
  int reduced_offset(int r) const { return blocks_[reduced_[r]].offset; }
  int ColumnPosition(int row, int col) const {
    const auto& cols = row_cols_[row];
    const int k = static_cast<int>(std::lower_bound(cols.begin(), cols.end(), col) - cols.begin());
    return row_col_pos_[row][k];
  }

  const SchurLMOptions& options_;
  ceres::Problem& problem_;
  std::vector<Block> blocks_;
  std::vector<Residual> residuals_;
  std::vector<int> points_, reduced_, free_;  // block indices: eliminated, reduced, not constant
  int num_reduced_ = 0, num_tangent_ = 0;

  // By point: its residuals, its reduced blocks (ascending) and their slots'
  // offsets in the W array (3 x tangent each).
  std::vector<std::vector<int>> point_residuals_, point_cams_, point_slot_offset_;
  // By reduced block row r: the blocks c >= r it shares a term with, their
  // positions in each scalar row, its residuals, its points (point, slot).
  std::vector<std::vector<int>> row_cols_, row_col_pos_, row_residuals_;
  std::vector<std::vector<std::pair<int, int>>> row_points_;
  // By bounded reduced block: where it is a column of the rows above its own (row, position).
  std::unordered_map<int, std::vector<std::pair<int, int>>> bounded_columns_;

  std::vector<double> plus_jacobians_, jacobians_, residual_values_, residual_cost_, scale_;
  std::vector<double> w_;              // by point and slot: W = Jp^T Jc (3 x tangent)
  std::vector<double> gradient_, model_;
  std::vector<double> saved_;  // the free blocks' values before a candidate step

  // With CHOLMOD and two threads or more, the step at the next smaller radius
  // is computed beside the current one (speculation): a rejected step then
  // costs no factorisation of its own. Either way the steps are the same bits.
  bool speculate_ = false;
  std::array<Damped, 2> damped_;
  SuiteSparse_long* colptr_ = nullptr;  // the pattern both systems share

  SchurLMSummary summary_;
};

std::string Solver::Structure(const std::vector<double*>& eliminate) {
  std::vector<double*> all;
  problem_.GetParameterBlocks(&all);
  std::unordered_map<const double*, int> index;
  std::unordered_map<const double*, bool> to_eliminate;
  for (double* p : eliminate) to_eliminate[p] = true;
  for (double* p : all) {
    Block b;
    b.values = p;
    b.size = problem_.ParameterBlockSize(p);
    b.tangent = problem_.ParameterBlockTangentSize(p);
    b.manifold = problem_.GetManifold(p);
    b.constant = problem_.IsParameterBlockConstant(p);
    bool bounded = false;
    for (int i = 0; i < b.size; ++i)
      bounded |= problem_.GetParameterLowerBound(p, i) > -std::numeric_limits<double>::max() ||
                 problem_.GetParameterUpperBound(p, i) < std::numeric_limits<double>::max();
    if (bounded)
      for (int i = 0; i < b.size; ++i) {
        b.lower.push_back(problem_.GetParameterLowerBound(p, i));
        b.upper.push_back(problem_.GetParameterUpperBound(p, i));
      }
    if (bounded && b.manifold && !b.constant) return "bounds on a block with a manifold are not supported";
    if (to_eliminate.count(p) && !b.constant) {
      if (b.size != 3 || b.tangent != 3 || b.manifold || bounded)
        return "an eliminated block must be 3 free coordinates without manifold or bounds";
      b.point = static_cast<int>(points_.size());
      points_.push_back(static_cast<int>(blocks_.size()));
    }
    index[p] = static_cast<int>(blocks_.size());
    blocks_.push_back(std::move(b));
  }

  std::vector<ceres::ResidualBlockId> ids;
  problem_.GetResidualBlocks(&ids);
  std::vector<int> uses(blocks_.size(), 0);  // points per reduced block, for its order
  point_residuals_.resize(points_.size());
  int values = 0;
  for (auto id : ids) {
    Residual r;
    r.cost = problem_.GetCostFunctionForResidualBlock(id);
    r.loss = problem_.GetLossFunctionForResidualBlock(id);
    r.size = r.cost->num_residuals();
    r.values = values;
    values += r.size;
    std::vector<double*> params;
    problem_.GetParameterBlocksForResidualBlock(id, &params);
    for (double* p : params) {
      const int b = index.at(p);
      r.blocks.push_back(b);
      if (blocks_[b].point >= 0 && !blocks_[b].constant) {
        if (r.point >= 0) return "a residual depends on two eliminated blocks";
        r.point = blocks_[b].point;
      }
    }
    if (r.point >= 0) {
      point_residuals_[r.point].push_back(static_cast<int>(residuals_.size()));
      for (int b : r.blocks)
        if (blocks_[b].point < 0 && !blocks_[b].constant) ++uses[b];
    }
    residuals_.push_back(std::move(r));
  }
  Order(uses);
  Storage();
  return "";
}

// Reduced blocks in ascending number of point terms (`uses`): the
// camera-wide blocks (intrinsics) come last, so the rows that own them hold
// few cells. Then every free block's place in the tangent vector.
void Solver::Order(const std::vector<int>& uses) {
  for (size_t b = 0; b < blocks_.size(); ++b)
    if (!blocks_[b].constant && blocks_[b].point < 0) reduced_.push_back(static_cast<int>(b));
  std::stable_sort(reduced_.begin(), reduced_.end(), [&](int a, int b) { return uses[a] < uses[b]; });
  num_reduced_ = static_cast<int>(reduced_.size());
  int offset = 0, plus = 0, saved = 0;
  for (int r = 0; r < num_reduced_; ++r) {
    blocks_[reduced_[r]].reduced = r;
    blocks_[reduced_[r]].offset = offset;
    offset += blocks_[reduced_[r]].tangent;
  }
  for (int b : points_) {
    blocks_[b].offset = offset;
    offset += 3;
  }
  num_tangent_ = offset;
  for (size_t i = 0; i < blocks_.size(); ++i) {
    Block& b = blocks_[i];
    if (b.constant) continue;
    free_.push_back(static_cast<int>(i));
    b.saved = saved;
    saved += b.size;
    if (b.manifold) {
      b.plus_jacobian = plus;
      plus += b.size * b.tangent;
    }
  }
  plus_jacobians_.resize(plus);
  saved_.resize(saved);
}

// Jacobian storage and the points' slots.
void Solver::Storage() {
  point_cams_.resize(points_.size());
  point_slot_offset_.resize(points_.size());
  int jac = 0;
  for (auto& r : residuals_) {
    for (int b : r.blocks) {
      r.jacobian.push_back(blocks_[b].constant ? -1 : jac);
      if (!blocks_[b].constant) jac += r.size * blocks_[b].tangent;
      if (r.point >= 0 && !blocks_[b].constant && blocks_[b].point < 0)
        point_cams_[r.point].push_back(blocks_[b].reduced);
    }
  }
  jacobians_.resize(jac);
  residual_values_.resize(residuals_.empty() ? 0 : residuals_.back().values + residuals_.back().size);
  residual_cost_.resize(residuals_.size());
  model_.resize(residuals_.size());
  int w = 0;
  for (size_t p = 0; p < points_.size(); ++p) {
    auto& cams = point_cams_[p];
    std::sort(cams.begin(), cams.end());
    cams.erase(std::unique(cams.begin(), cams.end()), cams.end());
    for (int c : cams) {
      point_slot_offset_[p].push_back(w);
      w += 3 * blocks_[reduced_[c]].tangent;
    }
  }
  for (auto& r : residuals_)
    for (int b : r.blocks) {
      int slot = -1;
      if (r.point >= 0 && !blocks_[b].constant && blocks_[b].point < 0) {
        const auto& cams = point_cams_[r.point];
        slot = static_cast<int>(std::lower_bound(cams.begin(), cams.end(), blocks_[b].reduced) - cams.begin());
      }
      r.point_slot.push_back(slot);
    }
  w_.resize(w);
  for (Damped& d : damped_) {
    d.e.resize(3 * points_.size());
    d.e_inverse.resize(9 * points_.size());
    d.rhs.resize(num_tangent_);
    d.step.resize(num_tangent_);
  }
  gradient_.resize(num_tangent_);
  scale_.assign(num_tangent_, 1.0);
}

// The reduced system's block pattern and CHOLMOD's symbolic analysis.
void Solver::Pattern() {
  row_cols_.assign(num_reduced_, {});
  row_residuals_.assign(num_reduced_, {});
  row_points_.assign(num_reduced_, {});
  for (size_t k = 0; k < residuals_.size(); ++k) {
    const Residual& r = residuals_[k];
    for (int b : r.blocks) {
      const int row = blocks_[b].reduced;
      if (row < 0) continue;
      row_residuals_[row].push_back(static_cast<int>(k));
      for (int c : r.blocks)
        if (blocks_[c].reduced >= row) row_cols_[row].push_back(blocks_[c].reduced);
    }
  }
  for (size_t p = 0; p < points_.size(); ++p) {
    const auto& cams = point_cams_[p];
    for (size_t s = 0; s < cams.size(); ++s) {
      row_points_[cams[s]].emplace_back(static_cast<int>(p), static_cast<int>(s));
      for (size_t t = s; t < cams.size(); ++t) row_cols_[cams[s]].push_back(cams[t]);
    }
  }
  SuiteSparse_long n = 0, nnz = 0;
  row_col_pos_.assign(num_reduced_, {});
  for (int r = 0; r < num_reduced_; ++r) {
    auto& cols = row_cols_[r];
    if (cols.empty() || cols.front() != r) cols.push_back(r);  // the diagonal block always
    std::sort(cols.begin(), cols.end());
    cols.erase(std::unique(cols.begin(), cols.end()), cols.end());
    int width = 0;
    for (int c : cols) {
      row_col_pos_[r].push_back(width);
      width += blocks_[reduced_[c]].tangent;
    }
    n += blocks_[reduced_[r]].tangent;
    nnz += static_cast<SuiteSparse_long>(width) * blocks_[reduced_[r]].tangent;
  }
  for (int r = 0; r < num_reduced_; ++r)
    for (size_t k = 0; k < row_cols_[r].size(); ++k) {
      const int c = row_cols_[r][k];
      if (c != r && !blocks_[reduced_[c]].lower.empty()) bounded_columns_[c].emplace_back(r, row_col_pos_[r][k]);
    }
  for (Damped& d : damped_) {
    cholmod_l_start(&d.common);
    d.started = true;
    d.common.print = 0;
  }
  Damped& first = damped_[0];
  first.matrix = cholmod_l_allocate_sparse(n, n, nnz, /*sorted=*/1, /*packed=*/1, /*stype=*/-1, CHOLMOD_REAL, &first.common);
  colptr_ = static_cast<SuiteSparse_long*>(first.matrix->p);
  auto* rowind = static_cast<SuiteSparse_long*>(first.matrix->i);
  first.values = static_cast<double*>(first.matrix->x);
  SuiteSparse_long at = 0;
  for (int r = 0; r < num_reduced_; ++r)
    for (int a = 0; a < blocks_[reduced_[r]].tangent; ++a) {
      colptr_[reduced_offset(r) + a] = at;
      for (int c : row_cols_[r])
        for (int b = 0; b < blocks_[reduced_[c]].tangent; ++b) rowind[at++] = reduced_offset(c) + b;
    }
  colptr_[n] = at;
  std::fill(first.values, first.values + nnz, 0.0);
  Analyze(n, rowind);
}

// CHOLMOD's analysis of the pattern and the factorisation chosen for it.
void Solver::Analyze(SuiteSparse_long n, SuiteSparse_long* rowind) {
  Damped& first = damped_[0];
  if (n > 0) first.factor = cholmod_l_analyze(first.matrix, &first.common);
  summary_.reduced_columns = n;
  summary_.factor_nonzeros = first.common.lnz;
  summary_.factor_flops = first.common.fl;
  summary_.factorization = "CHOLMOD";
  if (first.factor && options_.factorization_tile > 0) {
    // Tiles when they cost at most tile_flop_ratio (2) times CHOLMOD's
    // operations: Eigen's products on whole tiles ran as fast at 1.7 times
    // the operations as ATLAS on CHOLMOD's supernodes (the demo's gt node),
    // and they use every thread. A sparser system stays with CHOLMOD. The
    // choice does not depend on the thread count, so neither do the bits.
    auto tiled = std::make_unique<TiledCholesky>();
    const std::string why = tiled->Analyze(n, colptr_, rowind, static_cast<SuiteSparse_long*>(first.factor->Perm),
                                           options_.factorization_tile);
    if (why.empty() && tiled->flops() <= options_.tile_flop_ratio * first.common.fl) {
      summary_.factor_nonzeros = static_cast<double>(tiled->stored_values());
      summary_.factor_flops = tiled->flops();
      summary_.factorization = "tiles of " + std::to_string(options_.factorization_tile);
      first.tiled = std::move(tiled);
    }
  }
  // Tiles use every thread themselves: none is left to speculate with.
  speculate_ = options_.num_threads >= 2 && n > 0 && !first.tiled;
  if (speculate_) {
    Damped& second = damped_[1];
    second.matrix = cholmod_l_copy_sparse(first.matrix, &second.common);
    second.values = static_cast<double*>(second.matrix->x);
    second.factor = cholmod_l_analyze(second.matrix, &second.common);  // the same ordering: same input
  }
}

// Residuals, robust-loss-corrected Jacobians in the tangent spaces, scaled
// by the Jacobi scaling (fixed at the first linearisation, as Ceres does).
bool Solver::Linearize(bool first) {
  const int threads = options_.num_threads;
  ParallelFor(static_cast<int>(blocks_.size()), threads, 64, [&](int i) {
    const Block& b = blocks_[i];
    if (b.plus_jacobian >= 0) b.manifold->PlusJacobian(b.values, &plus_jacobians_[b.plus_jacobian]);
  });
  std::atomic<bool> ok{true};
  const int count = static_cast<int>(residuals_.size());
  const int chunk = 256;
  ParallelFor((count + chunk - 1) / chunk, threads, 1, [&](int c) {
    std::vector<const double*> params;
    std::vector<double*> jac_ptrs;
    std::vector<double> ambient;
    for (int k = c * chunk; k < std::min(count, (c + 1) * chunk); ++k) {
      const Residual& r = residuals_[k];
      const size_t nb = r.blocks.size();
      params.resize(nb);
      jac_ptrs.resize(nb);
      size_t need = 0;
      for (size_t j = 0; j < nb; ++j) need += blocks_[r.blocks[j]].constant ? 0 : r.size * blocks_[r.blocks[j]].size;
      ambient.resize(need);
      size_t at = 0;
      for (size_t j = 0; j < nb; ++j) {
        const Block& b = blocks_[r.blocks[j]];
        params[j] = b.values;
        jac_ptrs[j] = b.constant ? nullptr : &ambient[at];
        if (!b.constant) at += r.size * b.size;
      }
      double* res = &residual_values_[r.values];
      if (!r.cost->Evaluate(params.data(), res, jac_ptrs.data())) {
        ok = false;
        continue;
      }
      // Tangent Jacobians: ambient x Plus Jacobian.
      for (size_t j = 0; j < nb; ++j) {
        const Block& b = blocks_[r.blocks[j]];
        if (b.constant) continue;
        MapRM out(&jacobians_[r.jacobian[j]], r.size, b.tangent);
        ConstMapRM in(jac_ptrs[j], r.size, b.size);
        if (b.plus_jacobian >= 0)
          out.noalias() = in * ConstMapRM(&plus_jacobians_[b.plus_jacobian], b.size, b.tangent);
        else
          out = in;
      }
      Robustify(k);
    }
  });
  if (!ok) return false;
  if (first) JacobiScaling();
  ParallelFor(count, threads, 256, [&](int k) {
    const Residual& r = residuals_[k];
    for (size_t j = 0; j < r.blocks.size(); ++j) {
      const Block& b = blocks_[r.blocks[j]];
      if (b.constant) continue;
      MapRM J(&jacobians_[r.jacobian[j]], r.size, b.tangent);
      for (int a = 0; a < b.tangent; ++a) J.col(a) *= scale_[b.offset + a];
    }
  });
  return true;
}

// Residual k's cost, then Triggs' correction (Ceres' Corrector): the
// robustified problem as a least-squares one with rescaled residuals and
// Jacobians.
void Solver::Robustify(int k) {
  const Residual& r = residuals_[k];
  const size_t nb = r.blocks.size();
  Eigen::Map<Eigen::VectorXd> rv(&residual_values_[r.values], r.size);
  const double sq = rv.squaredNorm();
  if (!r.loss) {
    residual_cost_[k] = 0.5 * sq;
    return;
  }
  double rho[3];
  r.loss->Evaluate(sq, rho);
  residual_cost_[k] = 0.5 * rho[0];
  const double sqrt_rho1 = std::sqrt(rho[1]);
  double residual_scaling = sqrt_rho1, alpha_sq_norm = 0;
  if (sq > 0 && rho[2] > 0) {
    const double alpha = 1.0 - std::sqrt(1.0 + 2.0 * sq * rho[2] / rho[1]);
    residual_scaling = sqrt_rho1 / (1 - alpha);
    alpha_sq_norm = alpha / sq;
  }
  for (size_t j = 0; j < nb; ++j) {
    const Block& b = blocks_[r.blocks[j]];
    if (b.constant) continue;
    MapRM J(&jacobians_[r.jacobian[j]], r.size, b.tangent);
    if (alpha_sq_norm == 0) {
      J *= sqrt_rho1;
    } else {
      const Eigen::RowVectorXd rtj = rv.transpose() * J;
      J = sqrt_rho1 * (J - alpha_sq_norm * rv * rtj);
    }
  }
  rv *= residual_scaling;
}

// Ceres' Jacobi scaling, from the first linearisation's column norms (each
// summed over its residuals in their order).
void Solver::JacobiScaling() {
  ParallelFor(static_cast<int>(blocks_.size()), options_.num_threads, 64, [&](int i) {
    const Block& b = blocks_[i];
    if (b.constant) return;
    const std::vector<int>& list = b.point >= 0 ? point_residuals_[b.point] : row_residuals_[b.reduced];
    Eigen::VectorXd norms = Eigen::VectorXd::Zero(b.tangent);
    for (int k : list) {
      const Residual& r = residuals_[k];
      const size_t j = std::find(r.blocks.begin(), r.blocks.end(), i) - r.blocks.begin();
      norms += ConstMapRM(&jacobians_[r.jacobian[j]], r.size, b.tangent).colwise().squaredNorm().transpose();
    }
    for (int a = 0; a < b.tangent; ++a) scale_[b.offset + a] = 1.0 / (1.0 + std::sqrt(norms[a]));
  });
}

// The cost at the parameters' current values; false when a residual cannot
// be evaluated there.
bool Solver::Cost(double* cost) {
  std::atomic<bool> ok{true};
  const int count = static_cast<int>(residuals_.size());
  const int chunk = 256;
  ParallelFor((count + chunk - 1) / chunk, options_.num_threads, 1, [&](int c) {
    std::vector<const double*> params;
    std::vector<double> res;
    for (int k = c * chunk; k < std::min(count, (c + 1) * chunk); ++k) {
      const Residual& r = residuals_[k];
      params.resize(r.blocks.size());
      for (size_t j = 0; j < r.blocks.size(); ++j) params[j] = blocks_[r.blocks[j]].values;
      res.resize(r.size);
      if (!r.cost->Evaluate(params.data(), res.data(), nullptr)) {
        ok = false;
        continue;
      }
      const double sq = Eigen::Map<Eigen::VectorXd>(res.data(), r.size).squaredNorm();
      double rho[3] = {sq, 1, 0};
      if (r.loss) r.loss->Evaluate(sq, rho);
      residual_cost_[k] = 0.5 * rho[0];
    }
  });
  if (!ok) return false;
  double sum = 0;
  for (double c : residual_cost_) sum += c;
  *cost = sum;
  return std::isfinite(sum);
}

// The Levenberg-Marquardt steps of the damped systems `first` and (when not
// null) `second`, each at its own radius, in their scaled coordinates: the
// points' terms once, each system's rows, both factorisations at once.
void Solver::Steps(Damped* first, Damped* second) {
  const int threads = options_.num_threads;
  Damped* systems[2] = {first, second};
  const int count = second ? 2 : 1;
  const double lo = options_.min_lm_diagonal, hi = options_.max_lm_diagonal;
  std::atomic<bool> point_ok[2] = {true, true};

  // Points: E, bp, W by slot (shared), then per system E^-1 and e = E^-1 bp.
  ParallelFor(static_cast<int>(points_.size()), threads, 64, [&](int p) {
    Eigen::Matrix3d E = Eigen::Matrix3d::Zero();
    Eigen::Vector3d bp = Eigen::Vector3d::Zero();
    const auto& slots = point_slot_offset_[p];
    const auto& cams = point_cams_[p];
    for (size_t s = 0; s < slots.size(); ++s)
      std::fill_n(&w_[slots[s]], 3 * blocks_[reduced_[cams[s]]].tangent, 0.0);
    const int pb = points_[p];
    for (int k : point_residuals_[p]) {
      const Residual& r = residuals_[k];
      const size_t jp = std::find(r.blocks.begin(), r.blocks.end(), pb) - r.blocks.begin();
      const double* Jp = &jacobians_[r.jacobian[jp]];  // m x 3
      const double* res = &residual_values_[r.values];
      for (int i = 0; i < r.size; ++i) {
        const Eigen::Vector3d row(Jp[3 * i], Jp[3 * i + 1], Jp[3 * i + 2]);
        E.noalias() += row * row.transpose();
        bp -= res[i] * row;
      }
      for (size_t j = 0; j < r.blocks.size(); ++j) {
        if (r.point_slot[j] < 0) continue;
        const int t = blocks_[r.blocks[j]].tangent;
        AddTransposeProduct(Jp, 3, &jacobians_[r.jacobian[j]], t, r.size, &w_[slots[r.point_slot[j]]]);
      }
    }
    for (int a = 0; a < 3; ++a) gradient_[blocks_[pb].offset + a] = -bp[a];
    for (int k = 0; k < count; ++k) {
      Damped& d = *systems[k];
      Eigen::Matrix3d damped = E;
      for (int a = 0; a < 3; ++a) damped(a, a) += std::clamp(E(a, a), lo, hi) / d.radius;
      const Eigen::LLT<Eigen::Matrix3d> llt(damped);
      if (llt.info() != Eigen::Success) {
        point_ok[k] = false;
        continue;
      }
      Eigen::Map<Eigen::Matrix3d> inverse(&d.e_inverse[9 * p]);
      inverse = llt.solve(Eigen::Matrix3d::Identity());
      Eigen::Map<Eigen::Vector3d> e(&d.e[3 * p]);
      e = inverse * bp;
    }
  });

  // Reduced rows, each (system, row) owned by one thread.
  ParallelFor(count * num_reduced_, threads, 16, [&](int i) {
    const int k = i / num_reduced_;
    if (point_ok[k]) AssembleRow(*systems[k], i % num_reduced_, k == 0);
  });
  for (int k = 0; k < count; ++k) {
    systems[k]->solved = point_ok[k];
    if (point_ok[k]) HoldActiveBounds(*systems[k]);
  }

  // The factorisations, the second beside the first (each CHOLMOD call is
  // serial on ATLAS; two systems have their own CHOLMOD workspaces).
  const auto t = Clock::now();
  if (second) {
    std::thread beside([this, second] { Factorize(*second); });
    Factorize(*first);
    beside.join();
  } else {
    Factorize(*first);
  }
  summary_.factorize_seconds += Since(t);
  for (int k = 0; k < count; ++k) Finish(*systems[k]);
}

// Row `row` of d's damped reduced system: A + D - W^T E^-1 W, and bc - W^T e.
void Solver::AssembleRow(Damped& d, int row, bool write_gradient) {
  const int tr = blocks_[reduced_[row]].tangent;
  const int off = reduced_offset(row);
  for (int a = 0; a < tr; ++a) std::fill(d.values + colptr_[off + a], d.values + colptr_[off + a + 1], 0.0);
  double rhs[kMaxTangent] = {};
  const int rb = reduced_[row];
  // S(row, col) += sign * X^T Y (X: n x tr, Y: n x tc, row-major).
  auto add = [&](int pos, const double* X, const double* Y, int tc, int n, double sign) {
    if (tr == 6 && tc == 6 && n == 3) {  // pose x pose through a point: most of the work
      using Block36 = Eigen::Matrix<double, 3, 6, Eigen::RowMajor>;
      const Eigen::Matrix<double, 6, 6, Eigen::RowMajor> block =
          sign * (Eigen::Map<const Block36>(X).transpose() * Eigen::Map<const Block36>(Y));
      for (int a = 0; a < 6; ++a) {
        double* out = d.values + colptr_[off + a] + pos;
        for (int b = 0; b < 6; ++b) out[b] += block(a, b);
      }
      return;
    }
    for (int a = 0; a < tr; ++a) {
      double* out = d.values + colptr_[off + a] + pos;
      for (int i = 0; i < n; ++i) {
        const double x = sign * X[i * tr + a];
        const double* y = Y + i * tc;
        for (int b = 0; b < tc; ++b) out[b] += x * y[b];
      }
    }
  };
  for (int k : row_residuals_[row]) {
    const Residual& r = residuals_[k];
    const size_t jr = std::find(r.blocks.begin(), r.blocks.end(), rb) - r.blocks.begin();
    const double* Jr = &jacobians_[r.jacobian[jr]];
    const double* res = &residual_values_[r.values];
    for (int i = 0; i < r.size; ++i)
      for (int a = 0; a < tr; ++a) rhs[a] -= Jr[i * tr + a] * res[i];
    for (size_t j = 0; j < r.blocks.size(); ++j) {
      const int col = blocks_[r.blocks[j]].reduced;
      if (col < row) continue;
      add(ColumnPosition(row, col), Jr, &jacobians_[r.jacobian[j]], blocks_[r.blocks[j]].tangent, r.size, 1.0);
    }
  }
  for (int a = 0; a < tr; ++a) {
    if (write_gradient) gradient_[off + a] = -rhs[a];
    double& diagonal = S(d, row, a, 0, a);  // the diagonal block is the row's first
    diagonal += std::clamp(diagonal, options_.min_lm_diagonal, options_.max_lm_diagonal) / d.radius;
  }
  double H[3 * kMaxTangent];  // E^-1 W_row (3 x tr)
  for (const auto& [p, slot] : row_points_[row]) {
    const auto& slots = point_slot_offset_[p];
    const auto& cams = point_cams_[p];
    const double* Wr = &w_[slots[slot]];
    const double* inverse = &d.e_inverse[9 * p];  // symmetric
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < tr; ++a)
        H[k * tr + a] = inverse[3 * k] * Wr[a] + inverse[3 * k + 1] * Wr[tr + a] + inverse[3 * k + 2] * Wr[2 * tr + a];
    const double* e = &d.e[3 * p];
    for (int a = 0; a < tr; ++a) rhs[a] -= Wr[a] * e[0] + Wr[tr + a] * e[1] + Wr[2 * tr + a] * e[2];
    for (size_t s = slot; s < slots.size(); ++s)
      add(ColumnPosition(row, cams[s]), H, &w_[slots[s]], blocks_[reduced_[cams[s]]].tangent, 3, -1.0);
  }
  for (int a = 0; a < tr; ++a) d.rhs[off + a] = rhs[a];
}

// Coordinates at a bound that the descent direction pushes out are held for
// this step: their rows and columns are removed from S (a unit diagonal, a
// zero right-hand side), which is the Schur complement of the problem
// without them.
void Solver::HoldActiveBounds(Damped& d) {
  for (int row = 0; row < num_reduced_; ++row) {
    const Block& b = blocks_[reduced_[row]];
    if (b.lower.empty()) continue;
    const int off = reduced_offset(row);
    for (int a = 0; a < b.tangent; ++a) {
      const double g = gradient_[off + a];
      if (!((b.values[a] <= b.lower[a] && g > 0) || (b.values[a] >= b.upper[a] && g < 0))) continue;
      std::fill(d.values + colptr_[off + a], d.values + colptr_[off + a + 1], 0.0);
      for (int a2 = 0; a2 < b.tangent; ++a2) S(d, row, a2, 0, a) = 0;
      S(d, row, a, 0, a) = 1;
      d.rhs[off + a] = 0;
      if (auto it = bounded_columns_.find(row); it != bounded_columns_.end())
        for (const auto& [above, pos] : it->second)
          for (int a2 = 0; a2 < blocks_[reduced_[above]].tangent; ++a2) S(d, above, a2, pos, a) = 0;
    }
  }
}

// The reduced step of d (by its tiles or CHOLMOD); d.solved false when d is not positive
// definite, d.failed on an error. Touches only d (runs beside another system).
void Solver::Factorize(Damped& d) {
  const int n = static_cast<int>(d.matrix ? d.matrix->nrow : 0);
  if (!d.solved || n == 0) return;
  if (d.tiled) {
    d.solved = d.tiled->Factorize(d.values, options_.num_threads);
    if (d.solved) d.tiled->Solve(d.rhs.data(), d.step.data());
    return;
  }
  cholmod_l_factorize(d.matrix, d.factor, &d.common);
  if (d.common.status < CHOLMOD_OK)
    d.failed = "CHOLMOD failed to factorise the reduced system (status " + std::to_string(d.common.status) + ")";
  if (d.common.status == CHOLMOD_NOT_POSDEF || d.common.status < CHOLMOD_OK) {
    d.solved = false;
    return;
  }
  cholmod_dense* b = cholmod_l_allocate_dense(n, 1, n, CHOLMOD_REAL, &d.common);
  if (!b) {
    d.failed = "CHOLMOD could not allocate the right-hand side (status " + std::to_string(d.common.status) + ")";
    d.solved = false;
    return;
  }
  std::copy(d.rhs.begin(), d.rhs.begin() + n, static_cast<double*>(b->x));
  cholmod_dense* x = cholmod_l_solve(CHOLMOD_A, d.factor, b, &d.common);
  cholmod_l_free_dense(&b, &d.common);
  if (!x) {
    d.failed = "CHOLMOD failed to solve the reduced system (status " + std::to_string(d.common.status) + ")";
    d.solved = false;
    return;
  }
  std::copy(static_cast<double*>(x->x), static_cast<double*>(x->x) + n, d.step.begin());
  cholmod_l_free_dense(&x, &d.common);
}

// After the reduced solve: the points' steps, the step shortened at a bound,
// and the decrease it predicts.
void Solver::Finish(Damped& d) {
  if (!d.solved) return;
  const int threads = options_.num_threads;
  // Points: dp = e - E^-1 W dc.
  ParallelFor(static_cast<int>(points_.size()), threads, 256, [&](int p) {
    Eigen::Vector3d wd = Eigen::Vector3d::Zero();
    const auto& slots = point_slot_offset_[p];
    const auto& cams = point_cams_[p];
    for (size_t s = 0; s < slots.size(); ++s) {
      const int tc = blocks_[reduced_[cams[s]]].tangent;
      wd.noalias() += ConstMapRM(&w_[slots[s]], 3, tc) *
                      Eigen::Map<const Eigen::VectorXd>(&d.step[reduced_offset(cams[s])], tc);
    }
    const Eigen::Vector3d dp =
        Eigen::Map<const Eigen::Vector3d>(&d.e[3 * p]) - Eigen::Map<const Eigen::Matrix3d>(&d.e_inverse[9 * p]) * wd;
    Eigen::Map<Eigen::Vector3d> out(&d.step[blocks_[points_[p]].offset]);
    out = dp;
  });

  // A step that would cross a bound is shortened to reach it (the
  // coordinate is then held by HoldActiveBounds at the next step).
  double fraction = 1;
  for (int row = 0; row < num_reduced_; ++row) {
    const Block& b = blocks_[reduced_[row]];
    for (size_t a = 0; a < b.lower.size(); ++a) {
      const double delta = scale_[b.offset + a] * d.step[b.offset + a];
      if (b.values[a] + delta > b.upper[a] && delta > 0)
        fraction = std::min(fraction, std::max(0.0, b.upper[a] - b.values[a]) / delta);
      if (b.values[a] + delta < b.lower[a] && delta < 0)
        fraction = std::min(fraction, std::max(0.0, b.lower[a] - b.values[a]) / delta);
    }
  }
  if (fraction < 1)
    for (double& x : d.step) x *= fraction;

  // Predicted decrease: -(r^T J d + 0.5 |J d|^2), summed in residual order.
  ParallelFor(static_cast<int>(residuals_.size()), threads, 256, [&](int k) {
    const Residual& r = residuals_[k];
    double model = 0;
    for (int i = 0; i < r.size; ++i) {
      double jd = 0;  // row i of J d
      for (size_t j = 0; j < r.blocks.size(); ++j) {
        const Block& b = blocks_[r.blocks[j]];
        if (b.constant) continue;
        const double* J = &jacobians_[r.jacobian[j]] + i * b.tangent;
        for (int a = 0; a < b.tangent; ++a) jd += J[a] * d.step[b.offset + a];
      }
      model += residual_values_[r.values + i] * jd + 0.5 * jd * jd;
    }
    model_[k] = model;
  });
  double change = 0;
  for (double m : model_) change -= m;
  d.model_change = change;
  if (!std::isfinite(change)) d.solved = false;
}

void Solver::Save() {
  for (int i : free_) std::copy_n(blocks_[i].values, blocks_[i].size, &saved_[blocks_[i].saved]);
}

void Solver::Restore() {
  for (int i : free_) std::copy_n(&saved_[blocks_[i].saved], blocks_[i].size, blocks_[i].values);
}

// x <- Plus(x, scale .* step), projected onto the bounds (from the saved x).
void Solver::Candidate(const std::vector<double>& step) {
  ParallelFor(static_cast<int>(free_.size()), options_.num_threads, 256, [&](int f) {
    Block& b = blocks_[free_[f]];
    const double* x = &saved_[b.saved];
    double delta[kMaxTangent];
    for (int k = 0; k < b.tangent; ++k) delta[k] = scale_[b.offset + k] * step[b.offset + k];
    if (b.manifold)
      b.manifold->Plus(x, delta, b.values);
    else
      for (int k = 0; k < b.size; ++k) b.values[k] = x[k] + delta[k];
    for (size_t k = 0; k < b.lower.size(); ++k) b.values[k] = std::clamp(b.values[k], b.lower[k], b.upper[k]);
  });
}

double Solver::StepNorm(const std::vector<double>& step) const {
  double sq = 0;
  for (int i = 0; i < num_tangent_; ++i) sq += (scale_[i] * step[i]) * (scale_[i] * step[i]);
  return std::sqrt(sq);
}

double Solver::StateNorm() const {
  double sq = 0;
  for (int i : free_)
    for (int k = 0; k < blocks_[i].size; ++k) sq += blocks_[i].values[k] * blocks_[i].values[k];
  return std::sqrt(sq);
}

SchurLMSummary Solver::Run(const std::vector<double*>& eliminate) {
  const auto start = Clock::now();
  double cost = 0;
  std::string message = Prepare(eliminate, &cost);
  if (message.empty()) message = Iterate(cost);
  summary_.message = message;
  summary_.total_seconds = Since(start);
  return summary_;
}

// The problem's structure, the reduced pattern and the first linearisation;
// "" or why the problem cannot be solved here.
std::string Solver::Prepare(const std::vector<double*>& eliminate, double* cost) {
  if (const std::string why = options_.CheckMessage(); !why.empty()) return "invalid options: " + why;
  if (const std::string why = Structure(eliminate); !why.empty()) return why;
  for (const auto& b : blocks_)
    if (b.tangent > kMaxTangent)
      return "a parameter block has more than " + std::to_string(kMaxTangent) + " tangent coordinates";
  if (num_tangent_ == 0) return "no free parameter";
  Pattern();
  if (num_reduced_ > 0 && (!damped_[0].factor || (speculate_ && !damped_[1].factor)))
    return "CHOLMOD could not analyse the reduced system";
  const auto t = Clock::now();
  if (!Cost(cost) || !Linearize(true)) return "the residuals cannot be evaluated at the start";
  summary_.evaluate_seconds += Since(t);
  summary_.initial_cost = summary_.final_cost = *cost;
  summary_.usable = true;
  return "";
}

// The trust-region iterations from a linearised point of cost `cost`; why they stopped.
std::string Solver::Iterate(double cost) {
  double radius = options_.initial_trust_region_radius, decrease = 2;
  int current = 0;           // damped_[current]: the system of this step
  bool spare_ready = false;  // damped_[current] already holds the step at `radius` (speculated)
  while (summary_.iterations < options_.max_iterations) {
    if (options_.cancelled && options_.cancelled()) {
      summary_.cancelled = true;
      return "cancelled";
    }
    ++summary_.iterations;
    Damped& d = damped_[current];
    Damped* spare = speculate_ ? &damped_[1 - current] : nullptr;
    bool spare_computed = false;
    if (!spare_ready) {
      const auto t = Clock::now();
      d.radius = radius;
      if (spare) spare->radius = radius / decrease;  // the radius after a rejection, bit for bit
      Steps(&d, spare);
      spare_computed = spare != nullptr;
      summary_.step_seconds += Since(t);
    }
    spare_ready = false;
    if (!d.failed.empty()) {
      summary_.usable = false;
      return d.failed;
    }
    if (d.solved) {  // the point and row passes filled the gradient
      double g = 0;
      for (int i = 0; i < num_tangent_; ++i) g = std::max(g, std::abs(gradient_[i] / scale_[i]));
      if (g <= options_.gradient_tolerance) {
        summary_.converged = true;
        --summary_.iterations;
        return "gradient tolerance reached";
      }
    }
    double new_cost = cost, rho = 0;
    std::string stop;
    const bool descends = d.solved && d.model_change > 0;
    if (descends && !TryStep(d, cost, &new_cost, &rho, &stop)) return stop;
    const bool accepted = descends && rho > options_.min_relative_decrease;
    if (options_.verbose)
      std::printf("schur_lm %3d: cost %.6e -> %.6e model %.3e radius %.2e %s\n", summary_.iterations, cost,
                  new_cost, d.model_change, radius, accepted ? "accepted" : "rejected");
    if (accepted) {
      radius = std::min(options_.max_trust_region_radius,
                        radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3)));
      decrease = 2;
      ++summary_.successful_steps;
      cost = new_cost;
      summary_.final_cost = cost;
      const auto t = Clock::now();
      // Cannot fail where the cost could be evaluated; if it does, stop at the last good point.
      if (!Linearize(false)) return "the Jacobians cannot be evaluated at an accepted step";
      summary_.evaluate_seconds += Since(t);
      continue;
    }
    radius /= decrease;
    decrease *= 2;
    if (spare_computed) {  // the next step is the spare's
      current = 1 - current;
      spare_ready = true;
    }
    if (radius < options_.min_trust_region_radius) {
      summary_.converged = true;
      return "minimum trust region radius reached";
    }
  }
  return "maximum number of iterations reached";
}

// Moves to d's step and evaluates the cost there (*new_cost, and *rho the
// ratio of actual to predicted decrease; the parameters are restored when
// the step will be rejected); false when a tolerance ends the solve (*stop
// says which, the parameters at the last accepted point).
bool Solver::TryStep(const Damped& d, double cost, double* new_cost, double* rho, std::string* stop) {
  if (StepNorm(d.step) <= options_.parameter_tolerance * (StateNorm() + options_.parameter_tolerance)) {
    summary_.converged = true;
    *stop = "parameter tolerance reached";
    return false;
  }
  Save();
  Candidate(d.step);
  const auto t = Clock::now();
  const bool valid = Cost(new_cost);
  summary_.evaluate_seconds += Since(t);
  if (valid && std::abs(cost - *new_cost) <= options_.function_tolerance * cost) {
    Restore();
    summary_.converged = true;
    *stop = "function tolerance reached";
    return false;
  }
  *rho = valid ? (cost - *new_cost) / d.model_change : 0;
  if (!valid) *new_cost = cost;
  if (!(*rho > options_.min_relative_decrease)) Restore();
  return true;
}

}  // namespace

SchurLMSummary SolveSchurLM(const SchurLMOptions& options, const std::vector<double*>& eliminate,
                            ceres::Problem* problem) {
  Solver solver(options, problem);
  return solver.Run(eliminate);
}

}  // namespace locforge::sfm

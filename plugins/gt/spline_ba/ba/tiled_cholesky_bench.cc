// TiledCholesky against CHOLMOD (on the machine's BLAS) on reduced systems
// shaped like a bundle adjustment's (reduced_systems.h), same ordering:
// CHOLMOD's factorisation is the baseline of the same run; read the ratios.
//
//   locforge_tiled_cholesky_bench [--benchmark_filter=...]
// Arguments: poses (6 x 6 blocks), loops per pose x 10 (loop closures: the
// fill), tile, threads. Counters: the factorisation's GFLOP and the factor's
// stored values (millions).
#include <benchmark/benchmark.h>
#include <cholmod.h>

#include <map>
#include <memory>
#include <tuple>

#include "reduced_systems.h"
#include "tiled_cholesky.h"

namespace {

using locforge::sfm::MakeSystem;
using locforge::sfm::Sparse;
using locforge::sfm::TiledCholesky;

// One system per shape, shared by the benchmarks of that shape.
const Sparse& System(int poses, int loops_x10) {
  static std::map<std::pair<int, int>, std::unique_ptr<Sparse>> systems;
  auto& s = systems[{poses, loops_x10}];
  if (!s) s = std::make_unique<Sparse>(MakeSystem(poses, 3, poses * loops_x10 / 10, 1));
  return *s;
}

// CHOLMOD's matrix of the system (stype -1: the lower triangle), analysed.
struct Cholmod {
  explicit Cholmod(const Sparse& s) {
    cholmod_l_start(&common);
    common.print = 0;
    matrix = cholmod_l_allocate_sparse(s.n, s.n, s.row.size(), 1, 1, -1, CHOLMOD_REAL, &common);
    std::copy(s.start.begin(), s.start.end(), static_cast<SuiteSparse_long*>(matrix->p));
    std::copy(s.row.begin(), s.row.end(), static_cast<SuiteSparse_long*>(matrix->i));
    std::copy(s.value.begin(), s.value.end(), static_cast<double*>(matrix->x));
    factor = cholmod_l_analyze(matrix, &common);
  }
  ~Cholmod() {
    cholmod_l_free_factor(&factor, &common);
    cholmod_l_free_sparse(&matrix, &common);
    cholmod_l_finish(&common);
  }
  cholmod_common common{};
  cholmod_sparse* matrix = nullptr;
  cholmod_factor* factor = nullptr;
};

void BM_Cholmod(benchmark::State& state) {
  const Sparse& s = System(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  Cholmod c(s);
  for (auto _ : state) {
    cholmod_l_factorize(c.matrix, c.factor, &c.common);
    if (c.common.status != CHOLMOD_OK) state.SkipWithError("CHOLMOD failed");
  }
  state.counters["GFLOP"] = c.common.fl / 1e9;
  state.counters["Mvalues"] = c.common.lnz / 1e6;
}

void BM_Tiled(benchmark::State& state) {
  const Sparse& s = System(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  Cholmod c(s);  // for its ordering
  TiledCholesky tiled;
  if (!tiled.Analyze(s.n, s.start.data(), s.row.data(), static_cast<SuiteSparse_long*>(c.factor->Perm),
                     static_cast<int>(state.range(2))).empty())
    state.SkipWithError("Analyze failed");
  for (auto _ : state)
    if (!tiled.Factorize(s.value.data(), static_cast<int>(state.range(3)))) state.SkipWithError("not positive definite");
  state.counters["GFLOP"] = tiled.flops() / 1e9;
  state.counters["Mvalues"] = tiled.stored_values() / 1e6;
}

// A dense-ish system (many loops, like the demo's and large's: factor ~75 % of
// a dense triangle) and a sparse one (few loops, like the tests' synthetic scene).
BENCHMARK(BM_Cholmod)->Args({400, 200})->Args({800, 2})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Tiled)
    ->ArgsProduct({{400}, {200}, {64, 128}, {1, 2}})
    ->ArgsProduct({{800}, {2}, {128}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();

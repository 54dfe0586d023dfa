// Mutual nearest-neighbour matching of two images' SIFT-sized descriptors:
// the AVX2 scan against the portable Eigen scan, in the same run.
//   build/bin/locforge_matching_bench
#include <benchmark/benchmark.h>

#include <random>

#include "matching.h"

namespace locforge::matching {
namespace {

DescriptorMatrix RandomUnitRows(int rows, int dims, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g;
  DescriptorMatrix d(rows, dims);
  for (int i = 0; i < d.size(); ++i) d.data()[i] = std::abs(g(rng));
  for (int i = 0; i < rows; ++i) d.row(i).normalize();
  return d;
}

// range(0): keypoints per image; range(1): 1 = AVX2 scan, 0 = portable scan.
void BM_MutualNn(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const DescriptorMatrix a = RandomUnitRows(n, 128, 1), b = RandomUnitRows(n, 128, 2);
  NnOptions options;
  options.use_avx2 = state.range(1) != 0;
  for (auto _ : state) benchmark::DoNotOptimize(MatchDescriptors(a, b, options));
  state.SetLabel(options.use_avx2 ? "avx2" : "portable");
  state.counters["pairs/s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_MutualNn)->ArgsProduct({{2000, 8000}, {0, 1}})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace locforge::matching

BENCHMARK_MAIN();

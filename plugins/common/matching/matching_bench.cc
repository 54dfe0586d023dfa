// Mutual nearest-neighbour matching of two images' SIFT-sized descriptors,
// every scan in the same run: float rows (AVX2 tiles, portable Eigen) and
// byte rows as SIFT stores them (VNNI tiles, portable integer Eigen).
//   build/bin/locforge_matching_bench
#include <benchmark/benchmark.h>

#include <random>

#include "matching.h"

namespace locforge::matching {
namespace {

// Byte rows shaped like RootSIFT x 512, and the same rows as normalised floats.
kapture::FeatureArray RandomSiftLikeRows(int rows, int dims, unsigned seed) {
  std::mt19937 rng(seed);
  std::exponential_distribution<double> e(1.0 / 40);
  std::vector<uint8_t> values(static_cast<size_t>(rows) * dims);
  for (auto& v : values) v = static_cast<uint8_t>(std::min(255.0, e(rng)));
  return kapture::FeatureArray::From(kapture::DType::kUint8, dims, values);
}

// range(0): keypoints per image; range(1): 0 = float portable, 1 = float
// AVX2, 2 = bytes portable, 3 = bytes VNNI (falls back to portable where the
// processor lacks it: see the label).
void BM_MutualNn(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const int scan = static_cast<int>(state.range(1));
  const kapture::FeatureArray a = RandomSiftLikeRows(n, 128, 1), b = RandomSiftLikeRows(n, 128, 2);
  NnOptions options;
  options.use_simd = scan % 2 == 1;
  if (scan < 2) {
    const DescriptorMatrix fa = NormalisedDescriptors(a), fb = NormalisedDescriptors(b);
    for (auto _ : state) benchmark::DoNotOptimize(MatchDescriptors(fa, fb, options));
  } else {
    const ByteDescriptors ba = *ByteDescriptorsOf(a), bb = *ByteDescriptorsOf(b);
    for (auto _ : state) benchmark::DoNotOptimize(MatchDescriptors(ba, bb, options));
  }
  static const char* const kLabels[] = {"float portable", "float avx2", "bytes portable", "bytes vnni"};
  state.SetLabel(kLabels[scan]);
  state.counters["pairs/s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_MutualNn)->ArgsProduct({{2000, 8000}, {0, 1, 2, 3}})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace locforge::matching

BENCHMARK_MAIN();

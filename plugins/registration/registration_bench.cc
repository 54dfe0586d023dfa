// Time of one registration of the small_gicp pair (voxel 0.25 m, from the
// identity) per back-end and thread count, each loaded as the host loads it.
// The downsampling, KD-trees and covariances are part of the timed call.
// After the runs, prints each time as a ratio to PCL GICP at 1 thread.
//   locforge_registration_bench --benchmark_repetitions=5
#include <benchmark/benchmark.h>

#include <cstdio>
#include <ctime>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "locforge/pointcloud_io.h"
#include "locforge/registration.h"
#include "locforge/runtime/registry.h"

namespace {

using namespace locforge;

struct Pair {
  PointCloud source, target;
};

const Pair& Data() {
  static const Pair p = [] {
    const std::filesystem::path dir = std::filesystem::path(LF_SHARED_DIR) / "data/registration/small_gicp_pair";
    return Pair{ReadPly(dir / "source.ply"), ReadPly(dir / "target.ply")};
  }();
  return p;
}

runtime::Registry& Plugins() {
  static runtime::Registry* r = [] {
    auto* reg = new runtime::Registry;
    reg->LoadFile(LF_REGISTRATION_PLUGIN);
    return reg;
  }();
  return *r;
}

std::map<std::string, double>& Medians() {
  static std::map<std::string, double> m;
  return m;
}

void Align(benchmark::State& state, const char* id) {
  const int threads = static_cast<int>(state.range(0));
  const runtime::StageEntry* stage = Plugins().Find(id);
  if (!stage) {
    state.SkipWithError("plugin not loaded");
    return;
  }
  std::vector<std::pair<std::string, std::string>> params = {{"voxel_size", "0.25"},
                                                             {"max_correspondence_distance", "1.0"}};
  // Our GICP's default Cauchy kernel changes the cost (and takes ~3x the
  // iterations): the comparison with PCL's GICP is at the same, plain cost.
  if (std::string(id) == "registration/gicp") params.emplace_back("robust_kernel", "none");
  runtime::StageInstance inst(*stage, runtime::CheckStageParams(*stage, params));
  const RegistrationBackend b(static_cast<const LfRegistrationInterface*>(inst.Component()),
                              inst.raw(), id, nullptr);
  const Pair& d = Data();
  RegistrationResult r;
  // Process CPU time (all threads): with free cores, wall time ~ this / threads.
  const std::clock_t cpu0 = std::clock();
  for (auto _ : state) {
    r = b.Align(d.source, d.target, Pose(), threads);
    benchmark::DoNotOptimize(r);
  }
  state.counters["cpu_ms_all_threads"] =
      1e3 * static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC / state.iterations();
  state.counters["iterations"] = r.iterations;
  state.counters["overlap"] = r.inlier_fraction;
}

BENCHMARK_CAPTURE(Align, pcl_gicp, "registration/pcl_gicp")->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(Align, gicp, "registration/gicp")->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(Align, icp_plane, "registration/icp_plane")->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// Console output plus tables of ratios against pcl_gicp at 1 thread and of
// each back-end's 1 vs 2 thread times (medians when repeated, else means).
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& r : runs) {
      const bool aggregate = r.run_type == Run::RT_Aggregate;
      if (aggregate && r.aggregate_name != "median") continue;
      if (!aggregate && has_aggregates_) continue;
      std::string name = r.benchmark_name();
      const auto cut = name.find("_median");
      if (cut != std::string::npos) name = name.substr(0, cut);
      times_[name] = r.GetAdjustedRealTime();
    }
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    const auto base = times_.find("Align/pcl_gicp/1/real_time");
    if (base == times_.end()) return;
    std::printf("\n%-32s %12s %10s\n", "benchmark", "ms", "x pcl_gicp/1");
    for (const auto& [name, ms] : times_)
      std::printf("%-32s %12.1f %10.2f\n", name.c_str(), ms, ms / base->second);
    // One row per back-end: both thread counts as ratios to pcl_gicp/1, and
    // its own 2-thread speed-up (time at 1 / time at 2), all from this run.
    std::printf("\n%-12s %12s %12s %14s %14s %12s\n", "back-end", "1 thread ms", "2 threads ms",
                "1t x pcl_gicp/1", "2t x pcl_gicp/1", "speed-up 1->2");
    for (const char* backend : {"pcl_gicp", "gicp", "icp_plane"}) {
      const auto one = times_.find(std::string("Align/") + backend + "/1/real_time");
      const auto two = times_.find(std::string("Align/") + backend + "/2/real_time");
      if (one == times_.end() || two == times_.end()) continue;
      std::printf("%-12s %12.1f %12.1f %14.2f %14.2f %12.2f\n", backend, one->second, two->second,
                  one->second / base->second, two->second / base->second, one->second / two->second);
    }
  }
  bool has_aggregates_ = false;

 private:
  std::map<std::string, double> times_;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  RatioReporter reporter;
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]).rfind("--benchmark_repetitions", 0) == 0) reporter.has_aggregates_ = true;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  return 0;
}

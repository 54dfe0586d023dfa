// Time and memory of the spline bundle adjustment on a synthetic problem
// sized like the simulator's `large` preset (plugins/source/simulator/README.md:
// 10 sequences, ~18 000 images): 10 cameras (5 at 2.5 Hz, 5 at 1 Hz), the
// sequence length chosen to give --images images.
//
//   locforge_spline_ba_bench [--images N] [--threads T] [--sequences S]
//                            [--density D] [--max-depth M] [--iterations I] [--verbose 1]
//                            [--solver auto|sparse_schur|iterative_schur]
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "resource_usage.h"
#include "spline_ba.h"
#include "synthetic.h"

namespace {

using locforge::sfm::CpuSeconds;
using locforge::sfm::PeakRssMb;

}  // namespace

int main(int argc, char** argv) {
  using namespace locforge::sfm;
  int images = 18000, threads = 2, sequences = 10, iterations = 50, verbose = 0;
  double density = 0.5, max_depth = 15;
  std::string solver = "auto";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--solver") {
      solver = argv[i + 1];
      continue;
    }
    const double v = std::atof(argv[i + 1]);
    if (a == "--images") images = static_cast<int>(v);
    else if (a == "--threads") threads = static_cast<int>(v);
    else if (a == "--sequences") sequences = static_cast<int>(v);
    else if (a == "--density") density = v;
    else if (a == "--max-depth") max_depth = v;
    else if (a == "--iterations") iterations = static_cast<int>(v);
    else if (a == "--verbose") verbose = static_cast<int>(v);
    else {
      std::fprintf(stderr, "unknown option %s\n", argv[i]);
      return 2;
    }
  }
  SyntheticOptions so;
  so.sequences = sequences;
  so.cameras = 10;
  so.duration_s = images / (sequences * (5 * 2.5 + 5 * 1.0));
  so.points_per_m2 = density;
  so.max_depth_m = max_depth;
  so.min_track_length = 3;
  const auto t0 = std::chrono::steady_clock::now();
  SyntheticScene scene = MakeSyntheticScene(so);
  const double gen_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double rss_scene = PeakRssMb();
  SplineBAOptions options;
  options.num_threads = threads;
  options.max_iterations = iterations;
  options.verbose = verbose != 0;
  options.linear_solver = solver;
  if (!options.Check()) {
    std::fprintf(stderr, "%s\n", options.CheckMessage().c_str());
    return 2;
  }
  BAProblem problem = scene.initial;
  const double cpu0 = CpuSeconds();
  const SplineBAResult r = RunSplineBA(options, &problem);
  const double ba_cpu = CpuSeconds() - cpu0;
  const SceneErrors e = CompareToTruth(problem, scene.truth);
  std::printf("| images | points | observations | solver | threads | scene s | BA wall s | BA CPU s | iterations | reproj px (initial -> final) | "
              "pose RMS cm / deg | peak RSS MB (after scene -> after BA) |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::printf("| %zu | %zu | %zu | %s | %d | %.1f | %.1f | %.1f | %d%s | %.2f -> %.3f | %.2f / %.3f | %.0f -> %.0f |\n",
              problem.images.size(), problem.points.size(), problem.observations.size(), solver.c_str(), threads, gen_s, r.seconds, ba_cpu,
              r.iterations, r.converged ? "" : " (limit)", r.initial_mean_reproj_px, r.final_mean_reproj_px,
              100 * e.position_rms_m, e.rotation_rms_deg, rss_scene, PeakRssMb());
  std::printf("solver: %s\n", r.message.c_str());
  return r.usable ? 0 : 1;
}

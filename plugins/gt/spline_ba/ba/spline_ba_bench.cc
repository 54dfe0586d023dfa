// Time and memory of the spline bundle adjustment on a synthetic problem
// sized like the simulator's `large` preset (plugins/source/simulator/README.md:
// 10 sequences, ~18 000 images): 10 cameras (5 at 2.5 Hz, 5 at 1 Hz), the
// sequence length chosen to give --images images.
//
//   locforge_spline_ba_bench [--images N] [--threads T] [--sequences S] [--density D]
//                            [--max-depth M] [--iterations I] [--verbose true]
//                            [--solver auto|sparse_schur|iterative_schur]   (--help: every option)
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "locforge/param_cli.h"
#include "resource_usage.h"
#include "spline_ba.h"
#include "synthetic.h"

namespace {

using locforge::sfm::CpuSeconds;
using locforge::sfm::PeakRssMb;

struct Options {
  int images = 18000, threads = 2, sequences = 10, iterations = 50;
  double density = 0.5, max_depth = 15;
  bool verbose = false;
  std::string solver = "auto";

  static void Declare(locforge::ParamSchema<Options>& s) {
    s.Add("images", &Options::images, "images of the synthetic problem (10 cameras, 5 at 2.5 Hz, 5 at 1 Hz)").Min(1);
    s.Add("threads", &Options::threads, "Ceres threads").Min(1);
    s.Add("sequences", &Options::sequences, "platform trajectories").Min(1);
    s.Add("density", &Options::density, "landmarks per m^2 of wall").Min(1e-6);
    s.Add("max_depth", &Options::max_depth, "farthest landmark a camera observes (m)").Min(0);
    s.Add("iterations", &Options::iterations, "solver iterations").Min(1);
    s.Add("verbose", &Options::verbose, "Ceres' per-iteration log");
    s.Add("solver", &Options::solver, "linear solver").Choices({"auto", "sparse_schur", "iterative_schur"});
  }
};

const char kUsageHead[] =
    "usage: locforge_spline_ba_bench [options]\n"
    "Time and memory of the spline BA on a synthetic problem sized like the simulator's `large`.\n";

}  // namespace

int main(int argc, char** argv) {
  using namespace locforge::sfm;
  Options o;
  if (const int code = locforge::ParseToolOptions(argc, argv, kUsageHead, &o); code >= 0) return code;
  SyntheticOptions so;
  so.sequences = o.sequences;
  so.cameras = 10;
  so.duration_s = o.images / (o.sequences * (5 * 2.5 + 5 * 1.0));
  so.points_per_m2 = o.density;
  so.max_depth_m = o.max_depth;
  so.min_track_length = 3;
  const auto t0 = std::chrono::steady_clock::now();
  SyntheticScene scene = MakeSyntheticScene(so);
  const double gen_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double rss_scene = PeakRssMb();
  SplineBAOptions options;
  options.num_threads = o.threads;
  options.max_iterations = o.iterations;
  options.verbose = o.verbose;
  options.linear_solver = o.solver;
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
              problem.images.size(), problem.points.size(), problem.observations.size(), o.solver.c_str(), o.threads, gen_s, r.seconds, ba_cpu,
              r.iterations, r.converged ? "" : " (limit)", r.initial_mean_reproj_px, r.final_mean_reproj_px,
              100 * e.position_rms_m, e.rotation_rms_deg, rss_scene, PeakRssMb());
  std::printf("solver: %s\n", r.message.c_str());
  return r.usable ? 0 : 1;
}

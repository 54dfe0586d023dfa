// Simulator throughput: images and scans per CPU-second, one table. Rows:
// every camera type and LiDAR of a preset on its own floor, then the large
// preset's floor and crowd (8x5 blocks, 3 people per 100 m^2): its 0.2 deg
// horizontal LiDAR and the preset's industrial camera among those people (the
// crowded rendering row). Every item is also produced by the reference ray
// casting (World::Cast: median BVH, every person on every ray), alternating
// with the fast path in the same threads, for the speed-up column.
//   locforge_sim_bench [--preset small] [--images 24] [--scans 10] [--threads 2] [--dataset DIR]
//                      [--no-reference]
// --dataset also times a whole GenerateDataset run of the preset into DIR.
#include <algorithm>
#include <chrono>
#include <ctime>
#include <time.h>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <thread>

#include "dataset.h"
#include "lidar.h"
#include "render.h"

using namespace locforge::sim;

namespace {

double Seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// A floor, its crowd, the world on day 0 and a 30 s drive through it.
struct BenchWorld {
  BenchWorld(const std::string& name, const SimOptions& o, TextureLibrary* textures)
      : name(name), spec(GenerateFloor(o.floor, o.seed)), scene(BuildScene(spec)),
        crowd(MakeCrowd(spec, o.crowdedness, 1)), world(scene, crowd, textures, 0) {
    std::vector<Eigen::Vector2d> wp;
    std::mt19937_64 rng(1);
    for (int n : PlanRoute(spec.walk, spec.start_node, 60, rng)) wp.push_back(spec.walk.nodes[n]);
    traj = Drive(wp, {}, 0, o.limits, 30, 0.1);
  }
  std::string name;
  SceneSpec spec;
  Scene scene;
  Crowd crowd;
  World world;
  Trajectory traj;
};

double ThreadCpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

// Runs item(i, reference) for i in [0, items) on `threads` threads, the fast
// path and (when `reference`) the reference path for every item, alternating
// which goes first. Returns {wall seconds, cpu seconds fast, cpu seconds reference}.
struct Timing {
  double wall = 0, cpu = 0, cpu_reference = 0;
};
Timing Measure(int items, int threads, bool reference, const std::function<void(int, bool)>& item) {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<Timing> per_thread(threads);
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&, t] {
      for (int i = t; i < items; i += threads)
        for (int pass = 0; pass < (reference ? 2 : 1); ++pass) {
          const bool ref = reference && (pass == (i % 2 == 0 ? 1 : 0));
          const double c0 = ThreadCpuSeconds();
          item(i, ref);
          (ref ? per_thread[t].cpu_reference : per_thread[t].cpu) += ThreadCpuSeconds() - c0;
        }
    });
  for (auto& th : pool) th.join();
  Timing total;
  total.wall = Seconds(t0);
  for (const Timing& t : per_thread) {
    total.cpu += t.cpu;
    total.cpu_reference += t.cpu_reference;
  }
  return total;
}

void PrintRow(const std::string& sensor, const BenchWorld& w, int width, int height, int items, const Timing& t) {
  std::printf("%-10s %-8s %4dx%-5d %4zu %6d %12.2f", sensor.c_str(), w.name.c_str(), width, height,
              w.crowd.people().size(), items, items / t.cpu);
  if (t.cpu_reference > 0) std::printf(" %12.2f %8.2f", items / t.cpu_reference, t.cpu_reference / t.cpu);
  std::printf("\n");
}

void RenderRow(const BenchWorld& w, const CameraOptions& cam, int images, int threads, bool reference) {
  const Timing t = Measure(images, threads, reference, [&](int i, bool ref) {
    const double time = w.traj.duration() * i / images;
    RenderOptions o;
    o.reference_raycast = ref;
    RenderedImage img;
    Render(w.world, w.crowd.At(time), cam.intrinsics, w.traj.PoseAt(time) * cam.T_platform_camera, o, &img);
  });
  PrintRow(cam.id, w, cam.intrinsics.width, cam.intrinsics.height, images, t);
}

void LidarRow(const BenchWorld& w, const LidarOptions& lidar, int scans, int threads, bool reference) {
  const Timing t = Measure(scans, threads, reference, [&](int k, bool ref) {
    SimulateScan(w.world, w.traj, lidar, w.traj.duration() * k / scans, k, ref);
  });
  PrintRow(lidar.id, w, lidar.columns(), lidar.rings, scans, t);
}

}  // namespace

int main(int argc, char** argv) {
  std::string preset = "small", dataset;
  int images = 24, scans = 10, threads = 2;
  bool reference = true;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--no-reference")) {
      reference = false;
      continue;
    }
    if (!std::strcmp(argv[i], "--help") || !std::strcmp(argv[i], "-h") || i + 1 >= argc) {
      std::printf("usage: locforge_sim_bench [--preset tiny|small|large] [--images N] [--scans N] [--threads N] "
                  "[--dataset DIR] [--no-reference]\n");
      return std::strcmp(argv[i], "--help") && std::strcmp(argv[i], "-h") ? 2 : 0;
    }
    if (!std::strcmp(argv[i], "--preset")) preset = argv[++i];
    else if (!std::strcmp(argv[i], "--images")) images = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--scans")) scans = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--threads")) threads = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--dataset")) dataset = argv[++i];
    else {
      std::fprintf(stderr, "error: unknown option '%s' (--help)\n", argv[i]);
      return 2;
    }
  }
  threads = std::max(1, threads);
  try {
    const SimOptions o = PresetOptions(preset);
    const SimOptions large = PresetOptions("large");
    TextureLibrary textures(o.texture_size);
    const auto own = std::make_unique<BenchWorld>(preset, o, &textures);
    SimOptions crowded = large;
    crowded.seed = o.seed;
    const auto big = std::make_unique<BenchWorld>("large", crowded, &textures);
    const Rig rig = MakeRig(o.rig, 0), large_rig = MakeRig(large.rig, 0);

    std::printf("simulator benchmark, preset %s: %zu quads; large floor: %zu quads; %d thread(s)\n", preset.c_str(),
                own->scene.quads.size(), big->scene.quads.size(), threads);
    std::printf("%-10s %-8s %-10s %4s %6s %12s", "sensor", "floor", "size", "ppl", "items", "items/cpu-s");
    if (reference) std::printf(" %12s %8s", "reference", "speed-up");
    std::printf("\n");
    for (const char* group : {"ind", "phone"})
      for (const auto& c : rig.cameras)
        if (c.id.rfind(group, 0) == 0) {
          RenderRow(*own, c, images, threads, reference);
          break;
        }
    for (const auto& lidar : rig.lidars) LidarRow(*own, lidar, scans, threads, reference);
    LidarRow(*big, large_rig.lidars.front(), scans, threads, reference);
    RenderRow(*big, rig.cameras.front(), images, threads, reference);

    if (!dataset.empty()) {
      const auto t0 = std::chrono::steady_clock::now();
      const DatasetSummary s = GenerateDataset(o, dataset, threads);
      const double total = Seconds(t0);
      std::printf("dataset %s: %d images, %d scans in %.1f s (%.1f s rendering + encoding images)\n", preset.c_str(),
                  s.images, s.scans, total, s.render_seconds);
      for (const auto& q : s.sequences)
        std::printf("  %-8s %-10s %6.1f m  drift %.2f %%  %4d images  %3d scans  %3d people  %.1f %% person pixels\n",
                    q.plan.name.c_str(), q.plan.split.c_str(), q.distance_m, 100 * q.odometry_drift, q.images, q.scans,
                    q.people, 100 * q.person_fraction);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}

// Simulator throughput: images per second of the renderer and scans per
// second of the LiDAR model, one table. Rows: every camera type and LiDAR of
// a preset on its own floor, then the large preset's floor and crowd (8x5
// blocks, 3 people per 100 m^2): its 0.2 deg horizontal LiDAR and the preset's
// industrial camera among those people (the crowded rendering row).
//   locforge_sim_bench [--preset small] [--images 24] [--scans 10] [--threads 2] [--dataset DIR]
// --dataset also times a whole GenerateDataset run of the preset into DIR.
#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <cstring>
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

void PrintRow(const std::string& sensor, const BenchWorld& w, int width, int height, int items, double seconds,
              double cpu) {
  std::printf("%-10s %-8s %4dx%-5d %4zu %6d %10.2f %10.2f %12.2f\n", sensor.c_str(), w.name.c_str(), width,
              height, w.crowd.people().size(), items, items / seconds,
              double(items) * width * height / seconds / 1e6, items / cpu);
}

void RenderRow(const BenchWorld& w, const CameraOptions& cam, int images, int threads) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::clock_t c0 = std::clock();
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&, t] {
      RenderedImage img;
      for (int i = t; i < images; i += threads) {
        const double time = w.traj.duration() * i / images;
        Render(w.world, w.crowd.At(time), cam.intrinsics, w.traj.PoseAt(time) * cam.T_platform_camera,
               RenderOptions{}, &img);
      }
    });
  for (auto& th : pool) th.join();
  PrintRow(cam.id, w, cam.intrinsics.width, cam.intrinsics.height, images, Seconds(t0),
           double(std::clock() - c0) / CLOCKS_PER_SEC);
}

void LidarRow(const BenchWorld& w, const LidarOptions& lidar, int scans, int threads) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::clock_t c0 = std::clock();
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&, t] {
      for (int k = t; k < scans; k += threads) SimulateScan(w.world, w.traj, lidar, w.traj.duration() * k / scans, k);
    });
  for (auto& th : pool) th.join();
  PrintRow(lidar.id, w, lidar.columns(), lidar.rings, scans, Seconds(t0), double(std::clock() - c0) / CLOCKS_PER_SEC);
}

}  // namespace

int main(int argc, char** argv) {
  std::string preset = "small", dataset;
  int images = 24, scans = 10, threads = 2;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--help") || !std::strcmp(argv[i], "-h") || i + 1 >= argc) {
      std::printf("usage: locforge_sim_bench [--preset tiny|small|large] [--images N] [--scans N] [--threads N] "
                  "[--dataset DIR]\n");
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
    std::printf("%-10s %-8s %-10s %4s %6s %10s %10s %12s\n", "sensor", "floor", "size", "ppl", "items", "items/s",
                "Mrays/s", "items/cpu-s");
    for (const char* group : {"ind", "phone"})
      for (const auto& c : rig.cameras)
        if (c.id.rfind(group, 0) == 0) {
          RenderRow(*own, c, images, threads);
          break;
        }
    for (const auto& lidar : rig.lidars) LidarRow(*own, lidar, scans, threads);
    LidarRow(*big, large_rig.lidars.front(), scans, threads);
    RenderRow(*big, rig.cameras.front(), images, threads);

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

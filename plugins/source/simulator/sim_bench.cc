// Simulator throughput: images per second of the renderer and scans per
// second of the LiDAR model at a preset's resolution, one table.
//   locforge_sim_bench [--preset small] [--images 24] [--threads 2] [--dataset DIR]
// --dataset also times a whole GenerateDataset run of the preset into DIR.
#include <chrono>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <cstring>
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

}  // namespace

int main(int argc, char** argv) {
  std::string preset = "small", dataset;
  int images = 24, threads = 2;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--preset")) preset = argv[i + 1];
    else if (!std::strcmp(argv[i], "--images")) images = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--threads")) threads = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--dataset")) dataset = argv[i + 1];
  }
  try {
    const SimOptions o = PresetOptions(preset);
    const SceneSpec spec = GenerateFloor(o.floor, o.seed);
    const Scene scene = BuildScene(spec);
    const Crowd crowd = MakeCrowd(spec, o.crowdedness, 1);
    TextureLibrary textures(o.texture_size);
    const World world(scene, crowd, &textures, 0);
    const Rig rig = MakeRig(o.rig, 0);
    SequencePlan plan{"bench", "mapping", 0, 30, 0, 1};
    std::vector<Eigen::Vector2d> wp;
    std::mt19937_64 rng(1);
    for (int n : PlanRoute(spec.walk, spec.start_node, 60, rng)) wp.push_back(spec.walk.nodes[n]);
    const Trajectory traj = Drive(wp, {}, 0, o.limits, 30, 0.1);

    std::printf("simulator benchmark, preset %s: %zu quads, %zu people, %d thread(s)\n", preset.c_str(),
                scene.quads.size(), crowd.people().size(), threads);
    std::printf("%-12s %-10s %8s %10s %10s %14s\n", "sensor", "size", "items", "items/s", "Mrays/s", "items/cpu-s");
    for (const char* group : {"ind", "phone"}) {
      const CameraOptions* cam = nullptr;
      for (const auto& c : rig.cameras)
        if (c.id.rfind(group, 0) == 0) { cam = &c; break; }
      if (!cam) continue;
      const auto t0 = std::chrono::steady_clock::now();
      const std::clock_t c0 = std::clock();
      std::vector<std::thread> pool;
      for (int t = 0; t < threads; ++t)
        pool.emplace_back([&, t] {
          RenderedImage img;
          for (int i = t; i < images; i += threads) {
            const double time = traj.duration() * i / images;
            Render(world, crowd.At(time), cam->intrinsics, traj.PoseAt(time) * cam->T_platform_camera,
                   RenderOptions{}, &img);
          }
        });
      for (auto& th : pool) th.join();
      const double s = Seconds(t0), cpu = double(std::clock() - c0) / CLOCKS_PER_SEC;
      const double rays = double(images) * cam->intrinsics.width * cam->intrinsics.height;
      std::printf("%-12s %4dx%-5d %8d %10.2f %10.2f %14.2f\n", cam->id.c_str(), cam->intrinsics.width,
                  cam->intrinsics.height, images, images / s, rays / s / 1e6, images / cpu);
    }
    for (const auto& lidar : rig.lidars) {
      const int scans = 10;
      const auto t0 = std::chrono::steady_clock::now();
      const std::clock_t c0 = std::clock();
      size_t points = 0;
      for (int k = 0; k < scans; ++k) points += SimulateScan(world, traj, lidar, k * 0.5, k).points.size();
      const double s = Seconds(t0), cpu = double(std::clock() - c0) / CLOCKS_PER_SEC;
      std::printf("%-12s %4dx%-5d %8d %10.2f %10.2f %14.2f\n", lidar.id.c_str(), lidar.columns(), lidar.rings, scans,
                  scans / s, double(lidar.columns()) * lidar.rings * scans / s / 1e6, scans / cpu);
      (void)points;
    }
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

#include "dataset.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <map>
#include <mutex>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <thread>

#include "kapture_out.h"
#include "lidar.h"
#include "locforge/error.h"
#include "people.h"
#include "raycast.h"
#include "render.h"

namespace locforge::sim {

bool SimOptions::Check(std::string* why) const {
  if (scene_file.empty() && !floor.Check(why)) return false;
  if (!rig.Check(why) || !wheels.Check(why)) return false;
  if (mapping_sequences < 1) return *why = "at least one mapping sequence is needed", false;
  if (validation_sequences < 0 || test_sequences < 0) return *why = "query sequence counts must be >= 0", false;
  if (mapping_duration_s < 1 || query_duration_s < 1) return *why = "sequences must last at least 1 s", false;
  if (crowdedness < 0 || crowdedness > 50) return *why = "crowdedness must be in [0, 50] people per 100 m^2", false;
  if (query_crowdedness > 50) return *why = "query_crowdedness must be at most 50 people per 100 m^2", false;
  if (image_format != "jpg" && image_format != "png") return *why = "image_format must be jpg or png", false;
  if (layout != "splits" && layout != "single") return *why = "layout must be splits or single", false;
  if (texture_size < 32 || texture_size > 4096) return *why = "texture_size must be in [32, 4096]", false;
  return true;
}

SimOptions PresetOptions(const std::string& preset) {
  SimOptions o;
  if (preset == "tiny") {
    o.floor = {2, 1, 6.0, 6.0, 4.5, 4.0};
    o.rig.image_scale = 1.0 / 16;  // 162x128 and 135x180
    o.rig.lidar_azimuth_resolution_deg = 1.0;
    o.mapping_sequences = 1;
    o.mapping_duration_s = 8;
    o.query_duration_s = 4;
    o.texture_size = 256;
  } else if (preset == "small") {
    o.floor = {3, 2, 8.0, 6.0, 5.0, 4.0};
    o.rig.image_scale = 0.25;  // 648x512 and 540x720
    o.rig.lidar_azimuth_resolution_deg = 0.4;
    o.mapping_sequences = 2;
    o.mapping_duration_s = 16;
    o.query_duration_s = 8;
  } else if (preset == "large") {
    o.floor = {8, 5, 10.0, 8.0, 6.0, 5.0};
    o.rig.image_scale = 0.5;
    o.rig.lidar_azimuth_resolution_deg = 0.2;
    o.mapping_sequences = 6;
    o.validation_sequences = 2;
    o.test_sequences = 2;
    o.mapping_duration_s = 120;
    o.query_duration_s = 60;
    o.crowdedness = 3.0;
  } else {
    throw ParamError("unknown preset '" + preset + "' (tiny, small, large)");
  }
  return o;
}

std::vector<SequencePlan> PlanSequences(const SimOptions& o) {
  std::vector<SequencePlan> plans;
  const auto name = [](const char* prefix, int i) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%s_%02d", prefix, i);
    return std::string(buf);
  };
  const auto t0 = [](int day, int slot) {  // 09:00 + half hours, day after day
    return static_cast<Timestamp>((day * 86400LL + 9 * 3600LL + slot * 1800LL) * 1000000LL);
  };
  int last_day = 0;
  for (int i = 0; i < o.mapping_sequences; ++i) {
    last_day = i / 2;  // two mapping runs a day
    plans.push_back({name("map", i), "mapping", last_day, o.mapping_duration_s, t0(last_day, i % 2), 0});
  }
  for (int i = 0; i < o.validation_sequences; ++i)
    plans.push_back({name("val", i), "validation", last_day + 1, o.query_duration_s, t0(last_day + 1, i), 0});
  for (int i = 0; i < o.test_sequences; ++i)
    plans.push_back({name("test", i), "test", last_day + 2, o.query_duration_s, t0(last_day + 2, i), 0});
  for (size_t i = 0; i < plans.size(); ++i) plans[i].seed = o.seed * 1000003ull + 7919ull * (i + 1);
  return plans;
}

namespace {

uint64_t Mix(uint64_t a, uint64_t b) {
  uint64_t x = a * 0x9E3779B97F4A7C15ull ^ (b + 0x632BE59BD9B4E019ull);
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

Timestamp ToMicros(Timestamp t0, double seconds) { return t0 + static_cast<Timestamp>(std::llround(seconds * 1e6)); }

// Runs fn(i) for i in [0, n) on `threads` threads; rethrows the first error.
void ParallelFor(size_t n, int threads, const Hooks& hooks, const std::function<void(size_t)>& fn) {
  std::atomic<size_t> next{0};
  std::exception_ptr error;
  std::mutex mutex;
  const auto worker = [&] {
    while (true) {
      const size_t i = next++;
      if (i >= n) return;
      {
        std::lock_guard<std::mutex> lock(mutex);
        if (error) return;
      }
      try {
        if (hooks.cancelled && hooks.cancelled()) throw Cancelled();
        fn(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!error) error = std::current_exception();
        return;
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

// Where the mapping platform drove: each mapping trajectory sampled every
// `step_m` of travel.
using Path2d = std::vector<Eigen::Vector2d>;
std::vector<Path2d> MappedPaths(const std::vector<Trajectory>& mapping, double step_m) {
  std::vector<Path2d> paths;
  for (const Trajectory& t : mapping) {
    Path2d path;
    for (const PlanarState& s : t.states) {
      const Eigen::Vector2d p(s.x, s.y);
      if (path.empty() || (p - path.back()).norm() >= step_m) path.push_back(p);
    }
    paths.push_back(std::move(path));
  }
  return paths;
}

// The stretches of the mapped paths inside an area (x < split for
// validation, x >= split for test) of at least `min_samples` samples (1 m apart).
std::vector<Path2d> MappedRuns(const std::vector<Path2d>& paths, bool west, double split,
                               size_t min_samples = 4) {
  std::vector<Path2d> runs;
  for (const Path2d& path : paths) {
    Path2d run;
    for (size_t k = 0; k <= path.size(); ++k) {
      const bool inside = k < path.size() && ((path[k].x() < split) == west);
      if (inside) run.push_back(path[k]);
      if (!inside || k == path.size()) {
        if (run.size() >= min_samples) runs.push_back(run);
        run.clear();
      }
    }
  }
  return runs;
}

// The validation/test dividing line: the floor's query_split_x when the map
// was driven on both sides of it, else the median x of the mapped paths (a
// short mapping run may stay on one side).
double QuerySplitX(const SceneSpec& spec, const std::vector<Path2d>& mapped) {
  if (mapped.empty() || (!MappedRuns(mapped, true, spec.query_split_x).empty() &&
                         !MappedRuns(mapped, false, spec.query_split_x).empty())) {
    return spec.query_split_x;
  }
  std::vector<double> xs;
  for (const Path2d& path : mapped)
    for (const Eigen::Vector2d& p : path) xs.push_back(p.x());
  if (xs.empty()) return spec.query_split_x;
  std::nth_element(xs.begin(), xs.begin() + xs.size() / 2, xs.end());
  return xs[xs.size() / 2];
}

// A query revisits the mapped space, as in the paper's datasets (validation
// and test sequences recorded in the mapped floor on other days): it drives
// one mapped stretch of its area, back and forth, 0.3 m off the mapping line.
// Empty when the area has no mapped stretch.
std::vector<Eigen::Vector2d> QueryWaypoints(const std::vector<Path2d>& runs, double length_m,
                                            std::mt19937_64& rng) {
  if (runs.empty()) return {};
  std::uniform_real_distribution<double> u(-1, 1);
  Path2d run = runs[rng() % runs.size()];
  if (u(rng) > 0) std::reverse(run.begin(), run.end());
  const Eigen::Vector2d offset = 0.3 * Eigen::Vector2d(u(rng), u(rng));
  std::vector<Eigen::Vector2d> waypoints;
  double length = 0;
  for (int pass = 0; length < length_m && pass < 1000; ++pass) {
    for (size_t k = 0; k < run.size(); ++k) {
      const Eigen::Vector2d p = run[pass % 2 == 0 ? k : run.size() - 1 - k] + offset;
      if (!waypoints.empty()) length += (p - waypoints.back()).norm();
      if (waypoints.empty() || (p - waypoints.back()).norm() > 1e-6) waypoints.push_back(p);
    }
  }
  return waypoints;
}

// A sequence's route: mapping sequences take a random walk from (near) the
// start node; queries revisit a mapped stretch of their area (QueryWaypoints),
// or walk the graph inside their area when it has none.
Trajectory PlanTrajectory(const SceneSpec& spec, const SimOptions& o, const SequencePlan& plan,
                          const WheelOptions& wheels, const std::vector<Trajectory>& mapping,
                          const std::vector<Path2d>& mapped, double split_x) {
  std::mt19937_64 rng(Mix(plan.seed, 1));
  std::uniform_real_distribution<double> u(-1, 1);
  const WalkGraph& g = spec.walk;
  const double length = plan.duration_s * o.limits.max_speed * 1.5 + 20;
  if (plan.split == "validation" || plan.split == "test") {
    // Stretches of 3 m or more (samples 1 m apart); on a very short map, any
    // mapped stretch (samples 0.25 m apart).
    const bool west = plan.split == "validation";
    std::vector<Path2d> runs = MappedRuns(mapped, west, split_x);
    if (runs.empty()) runs = MappedRuns(MappedPaths(mapping, 0.25), west, split_x, 2);
    const std::vector<Eigen::Vector2d> waypoints = QueryWaypoints(runs, length, rng);
    if (waypoints.size() >= 2) {
      const Eigen::Vector2d first_leg = waypoints[1] - waypoints[0];
      const double yaw = std::atan2(first_leg.y(), first_leg.x()) + 0.3 * u(rng);
      return Drive(waypoints, std::vector<bool>(waypoints.size(), false), yaw, o.limits,
                   plan.duration_s, wheels.radius);
    }
  }
  SceneSpec area = spec;
  area.query_split_x = split_x;
  std::function<bool(int)> allowed;
  if (plan.split == "validation") allowed = [&](int n) { return g.nodes[n].x() < area.query_split_x; };
  if (plan.split == "test") allowed = [&](int n) { return g.nodes[n].x() >= area.query_split_x; };
  int start = spec.start_node;
  if (allowed && !allowed(start)) {  // nearest node inside the area
    double best = 1e18;
    for (size_t n = 0; n < g.nodes.size(); ++n)
      if (allowed(static_cast<int>(n)) && (g.nodes[n] - g.nodes[start]).norm() < best)
        best = (g.nodes[n] - g.nodes[start]).norm(), start = static_cast<int>(n);
  }
  const std::vector<int> route = PlanRoute(g, start, length, rng, allowed);
  std::vector<Eigen::Vector2d> waypoints{g.nodes[start] + 0.3 * Eigen::Vector2d(u(rng), u(rng))};
  std::vector<bool> spins{false};
  for (size_t i = 1; i < route.size(); ++i) {
    waypoints.push_back(g.nodes[route[i]]);
    spins.push_back(u(rng) > 0.6);  // ~20 % of the corners get a rapid full turn
  }
  const Eigen::Vector2d first_leg = waypoints.size() > 1 ? waypoints[1] - waypoints[0] : Eigen::Vector2d(1, 0);
  const double yaw = std::atan2(first_leg.y(), first_leg.x()) + 0.3 * u(rng);
  return Drive(waypoints, spins, yaw, o.limits, plan.duration_s, wheels.radius);
}

// Kapture root of a split, relative to the output: the mapping kapture is the
// output itself, queries live in validation/ and test/ (layout "splits").
std::string Folder(const SimOptions& o, const std::string& split) {
  return o.layout == "splits" && split != "mapping" ? split : "";
}

void WriteImage(const fs::path& path, const RenderedImage& img, const std::string& format) {
  cv::Mat rgb(img.height, img.width, CV_8UC3, const_cast<uint8_t*>(img.rgb.data())), bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  std::vector<uchar> bytes;
  const std::vector<int> params = format == "jpg" ? std::vector<int>{cv::IMWRITE_JPEG_QUALITY, 95} : std::vector<int>{};
  if (!cv::imencode("." + format, bgr, bytes, params)) throw Error("cannot encode " + path.string());
  WriteDataFile(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

void WriteMask(const fs::path& path, const RenderedImage& img) {
  cv::Mat mask(img.height, img.width, CV_8UC1, const_cast<uint8_t*>(img.person_mask.data()));
  std::vector<uchar> bytes;
  if (!cv::imencode(".png", mask, bytes)) throw Error("cannot encode " + path.string());
  WriteDataFile(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

// kapture's depth map file: width x height float32, row-major, little endian
// (the sizes are the camera's), z in metres, 0 where no surface.
void WriteDepth(const fs::path& path, const RenderedImage& img) {
  static_assert(sizeof(float) == 4);
  WriteDataFile(path, std::string_view(reinterpret_cast<const char*>(img.depth.data()), img.depth.size() * sizeof(float)));
}

std::string PoseYaml(const Pose& p) {
  const Eigen::Quaterniond q = p.q.normalized();
  return "{qw: " + FormatNumber(q.w()) + ", qx: " + FormatNumber(q.x()) + ", qy: " + FormatNumber(q.y()) +
         ", qz: " + FormatNumber(q.z()) + ", tx: " + FormatNumber(p.t.x()) + ", ty: " + FormatNumber(p.t.y()) +
         ", tz: " + FormatNumber(p.t.z()) + "}";
}

void WriteCalibration(const fs::path& path, const Rig& rig) {
  std::ostringstream y;
  y << "# True calibration of the simulated platform. Poses are sensor-to-platform (T_platform_sensor);\n"
    << "# camera timestamps = nominal trigger + clock_offset_s, true capture = nominal + N(0, jitter_s).\n";
  y << "cameras:\n";
  for (const auto& c : rig.cameras) {
    const auto& k = c.intrinsics;
    y << "  - {id: " << c.id << ", model: PINHOLE, width: " << k.width << ", height: " << k.height
      << ", fx: " << FormatNumber(k.fx) << ", fy: " << FormatNumber(k.fy) << ", cx: " << FormatNumber(k.cx)
      << ", cy: " << FormatNumber(k.cy) << ", rate_hz: " << FormatNumber(c.rate_hz)
      << ", clock_offset_s: " << FormatNumber(c.clock_offset_s) << ", jitter_s: " << FormatNumber(c.jitter_s)
      << ",\n     T_platform_sensor: " << PoseYaml(c.T_platform_camera) << "}\n";
  }
  y << "lidars:\n";
  for (const auto& l : rig.lidars)
    y << "  - {id: " << l.id << ", rings: " << l.rings << ", min_elevation_deg: " << FormatNumber(l.min_elevation_deg)
      << ", max_elevation_deg: " << FormatNumber(l.max_elevation_deg)
      << ", azimuth_resolution_deg: " << FormatNumber(l.azimuth_resolution_deg) << ", rate_hz: " << FormatNumber(l.rate_hz)
      << ", range_sigma_m: " << FormatNumber(l.range_sigma) << ", ring_firing_s: " << FormatNumber(l.ring_firing_s)
      << ",\n     T_platform_sensor: " << PoseYaml(l.T_platform_lidar) << "}\n";
  const auto& w = rig.wheels;
  y << "wheels: {radius_m: " << FormatNumber(w.radius) << ", axle_m: " << FormatNumber(w.axle)
    << ", pulses_per_rev: " << w.pulses_per_rev << ", rate_hz: " << FormatNumber(w.rate_hz)
    << ", scale_error_sigma: " << FormatNumber(w.scale_error) << ", differential_error_sigma: "
    << FormatNumber(w.differential_error) << ", slip_sigma_m_per_sqrt_m: " << FormatNumber(w.slip_sigma) << "}\n";
  WriteFileAtomic(path, y.str());
}

struct SequenceWork {
  SequencePlan plan;
  Trajectory trajectory;
  std::vector<std::pair<size_t, Capture>> captures;  // (camera index, capture)
  std::vector<std::pair<size_t, double>> scans;      // (lidar index, start time)
};

// One dataset's generation: the scene, the rig and every sequence's plan,
// then each sequence simulated into its kapture rows and files.
struct DatasetMaker {
  DatasetMaker(const SimOptions& o, const fs::path& out, int threads, const Hooks& hooks)
      : o(o),
        out(out),
        threads(threads),
        hooks(hooks),
        spec(o.scene_file.empty() ? GenerateFloor(o.floor, o.seed) : LoadSceneSpec(o.scene_file)),
        scene(BuildScene(spec)),
        rig(MakeRig(o.rig, o.seed)),
        textures(o.texture_size),
        truth(out / "truth") {
    rig.wheels = o.wheels;
  }

  const SimOptions& o;
  const fs::path& out;
  const int threads;
  const Hooks& hooks;
  const SceneSpec spec;
  const Scene scene;
  Rig rig;
  TextureLibrary textures;
  const fs::path truth;
  std::vector<SequenceWork> work;
  uint64_t total = 0;
  std::atomic<uint64_t> done{0};
  DatasetSummary summary;
  std::map<std::string, KaptureRows> kaptures;  // by folder
  std::string sequences_txt =
      "# name, split, day, t0_us, duration_s, distance_m, odometry_drift, images, scans, people, person_fraction\n";

  void Log(const std::string& m) const {
    if (hooks.log) hooks.log(m);
  }
  void Tick() {
    const uint64_t d = ++done;
    if (hooks.progress) hooks.progress(d, total);
  }

  // Plan every sequence first (cheap) so progress has a total: its path
  // (queries after the mapping sequences, which PlanSequences lists first),
  // its captures and its scans.
  void PlanWork() {
    std::vector<Trajectory> mapping;
    std::vector<Path2d> mapped;
    double split_x = spec.query_split_x;
    for (const SequencePlan& plan : PlanSequences(o)) {
      SequenceWork w;
      w.plan = plan;
      if (plan.split != "mapping" && mapped.empty() && !mapping.empty()) {
        mapped = MappedPaths(mapping, 1.0);
        split_x = QuerySplitX(spec, mapped);
      }
      w.trajectory = PlanTrajectory(spec, o, plan, rig.wheels, mapping, mapped, split_x);
      if (plan.split == "mapping") mapping.push_back(w.trajectory);
      const double duration = w.trajectory.duration();
      for (size_t c = 0; o.cameras && c < rig.cameras.size(); ++c)
        for (const Capture& cap : CaptureTimes(rig.cameras[c], duration, Mix(plan.seed, 100 + c)))
          w.captures.emplace_back(c, cap);
      if (o.lidar)
        for (size_t l = 0; l < rig.lidars.size(); ++l)
          for (int k = 0; (k + 1) / rig.lidars[l].rate_hz <= duration; ++k)
            w.scans.emplace_back(l, k / rig.lidars[l].rate_hz);
      total += w.captures.size() + w.scans.size();
      work.push_back(std::move(w));
    }
  }

  // Platform ground truth at 10 Hz, and the wheel encoders (with the drift
  // their integration accumulates over the sequence).
  void WritePlatform(const SequenceWork& w, KaptureRows& rows, SequenceSummary* ss) const {
    const SequencePlan& plan = w.plan;
    const Trajectory& traj = w.trajectory;
    for (double t = 0; t <= traj.duration() + 1e-9; t += 0.1)
      rows.trajectories.push_back({ToMicros(plan.t0_us, t), "rig", FormatPose(traj.PoseAt(t).Inverse())});
    const auto readings = SimulateEncoders(traj, rig.wheels, Mix(plan.seed, 3));
    for (const auto& r : readings)
      rows.records_wheel.push_back(
          {ToMicros(plan.t0_us, r.t), "wheels", std::to_string(r.left) + ", " + std::to_string(r.right)});
    const auto odometry = IntegrateEncoders(readings, rig.wheels, traj.states.front());
    if (!odometry.empty() && ss->distance_m > 0) {
      const PlanarState truth_end = traj.StateAt(odometry.back().t);
      ss->odometry_drift =
          std::hypot(odometry.back().x - truth_end.x, odometry.back().y - truth_end.y) / ss->distance_m;
    }
  }

  void SimulateScans(const SequenceWork& w, const World& world, const fs::path& data, KaptureRows& rows,
                     std::mutex& rows_mutex) {
    const SequencePlan& plan = w.plan;
    ParallelFor(w.scans.size(), threads, hooks, [&](size_t i) {
      const auto& [l, start] = w.scans[i];
      const LidarOptions& lidar = rig.lidars[l];
      const LidarScan scan = SimulateScan(world, w.trajectory, lidar, start, Mix(plan.seed, 1000000 + i));
      const Timestamp ts = ToMicros(plan.t0_us, start);
      const std::string rel = plan.name + "/" + lidar.id + "/" + std::to_string(ts) + ".pcd";
      WriteDataFile(data / rel, EncodePcd(scan));
      {
        std::lock_guard<std::mutex> lock(rows_mutex);
        rows.records_lidar.push_back({ts, lidar.id, rel});
      }
      Tick();
    });
  }

  // Camera images, person masks and per-camera ground truth: each image's
  // person fraction.
  std::vector<double> RenderImages(const SequenceWork& w, const World& world, const Crowd& crowd,
                                   const fs::path& data, KaptureRows& rows, std::mutex& rows_mutex) {
    const SequencePlan& plan = w.plan;
    const double exposure = 0.8 + 0.4 * (Mix(o.seed, 10 + plan.day) % 1000) / 1000.0;
    const double gain = 1.0 + 0.3 * (Mix(o.seed, 20 + plan.day) % 1000) / 1000.0;
    std::vector<double> person_fraction(w.captures.size(), 0);
    ParallelFor(w.captures.size(), threads, hooks, [&](size_t i) {
      const auto& [c, cap] = w.captures[i];
      const CameraOptions& cam = rig.cameras[c];
      const Pose T_world_camera = w.trajectory.PoseAt(cap.true_time) * cam.T_platform_camera;
      RenderOptions ro;
      ro.exposure = exposure;
      ro.gain = gain;
      ro.noise_seed = Mix(plan.seed, 5000000 + i);
      RenderedImage img;
      Render(world, crowd.At(cap.true_time), cam.intrinsics, T_world_camera, ro, &img);
      const Timestamp ts = ToMicros(plan.t0_us, cap.stamp);
      const std::string stem = plan.name + "/" + cam.id + "/" + std::to_string(ts);
      WriteImage(data / (stem + "." + o.image_format), img, o.image_format);
      if (o.masks) WriteMask(truth / "masks" / plan.split / (stem + ".png"), img);
      if (o.depth) WriteDepth(truth / "depth" / plan.split / (stem + ".depth"), img);
      person_fraction[i] = img.PersonFraction();
      {
        std::lock_guard<std::mutex> lock(rows_mutex);
        rows.records_camera.push_back({ts, cam.id, stem + "." + o.image_format});
        rows.trajectories.push_back({ts, cam.id, FormatPose(T_world_camera.Inverse())});
      }
      Tick();
    });
    return person_fraction;
  }

  // The sequence's line of truth/sequences.txt and of the log.
  void Record(const SequencePlan& plan, const Trajectory& traj, const SequenceSummary& ss) {
    char line[512];
    std::snprintf(line, sizeof(line), "%s, %s, %d, %lld, %.3f, %.3f, %.5f, %d, %d, %d, %.5f\n", plan.name.c_str(),
                  plan.split.c_str(), plan.day, static_cast<long long>(plan.t0_us), traj.duration(), ss.distance_m,
                  ss.odometry_drift, ss.images, ss.scans, ss.people, ss.person_fraction);
    sequences_txt += line;
    Log(plan.name + " (" + plan.split + ", day " + std::to_string(plan.day) +
        "): " + FormatNumber(std::round(ss.distance_m * 10) / 10) + " m, " + std::to_string(ss.images) +
        " images, " + std::to_string(ss.scans) + " scans, " + std::to_string(ss.people) + " people");
  }

  void Simulate(const SequenceWork& w) {
    const SequencePlan& plan = w.plan;
    const std::string folder = Folder(o, plan.split);
    KaptureRows& rows = kaptures[folder];
    if (rows.sensors.empty()) {
      AddRigSensors(rig, &rows);
      AddRigExtrinsics(rig, &rows);
    }
    const fs::path root = folder.empty() ? out : out / folder;
    const fs::path data = root / "sensors" / "records_data";
    const double density =
        plan.split != "mapping" && o.query_crowdedness >= 0 ? o.query_crowdedness : o.crowdedness;
    const Crowd crowd = MakeCrowd(spec, density, Mix(plan.seed, 2));
    const World world(scene, crowd, &textures, plan.day);
    SequenceSummary ss;
    ss.plan = plan;
    ss.distance_m = w.trajectory.Distance();
    ss.people = static_cast<int>(crowd.people().size());
    WritePlatform(w, rows, &ss);
    std::mutex rows_mutex;
    SimulateScans(w, world, data, rows, rows_mutex);
    ss.scans = static_cast<int>(w.scans.size());
    const auto t_render = std::chrono::steady_clock::now();
    const std::vector<double> person_fraction = RenderImages(w, world, crowd, data, rows, rows_mutex);
    summary.render_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t_render).count();
    ss.images = static_cast<int>(w.captures.size());
    for (double f : person_fraction) ss.person_fraction += f / std::max<size_t>(1, person_fraction.size());
    summary.images += ss.images;
    summary.scans += ss.scans;
    Record(plan, w.trajectory, ss);
    summary.sequences.push_back(ss);
  }
};

}  // namespace

DatasetSummary GenerateDataset(const SimOptions& o, const fs::path& out, int threads, const Hooks& hooks) {
  std::string why;
  if (!o.Check(&why)) throw ParamError(why);
  DatasetMaker m(o, out, std::max(1, threads), hooks);
  m.Log("scene: " + std::to_string(m.scene.quads.size()) + " quads, " + std::to_string(m.scene.materials.size()) +
        " materials, floor " + FormatNumber(m.spec.x1 - m.spec.x0) + " x " + FormatNumber(m.spec.y1 - m.spec.y0) +
        " m");
  m.PlanWork();
  for (const SequenceWork& w : m.work) m.Simulate(w);
  for (auto& [folder, rows] : m.kaptures) WriteKaptureText(folder.empty() ? out : out / folder, std::move(rows));
  WriteCalibration(m.truth / "calibration.yaml", m.rig);
  WriteFileAtomic(m.truth / "sequences.txt", m.sequences_txt);
  return m.summary;
}

}  // namespace locforge::sim

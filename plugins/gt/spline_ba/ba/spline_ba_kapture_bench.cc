// Time and memory of the spline bundle adjustment on a problem built from a
// real recording's geometry: the image timestamps, cameras, rig and true
// per-image poses of a kapture recording (e.g. the simulator's `large`
// preset) and the platform trajectories of its LiDAR SLAM (slam/pose_graph
// output), with SYNTHETIC landmarks and observations (features cannot be
// extracted from the 1 %-resolution images of a LiDAR-only large run):
//
//  * cameras: the recording's intrinsics multiplied by --intrinsics-scale
//    (100 gives the full-resolution 2600x2000 / 2200x2900 cameras of a
//    recording simulated at scale 0.01), extrinsics from rigs.txt;
//  * per image, --seeds landmarks at a random pixel and a depth uniform in
//    [--min-depth-m, --max-depth-m] of the TRUE camera pose; each landmark is
//    observed by every image whose true centre lies within --max-depth-m of it
//    (grid of camera centres), that sees it in front within the image, and
//    whose viewing ray differs by < --max-angle-deg from the seed's; tracks
//    longer than --max-track are subsampled (the seed kept), tracks < 2 dropped;
//  * observations: true projection + N(0, --pixel-noise-px^2) per coordinate;
//  * start: image poses and platform trajectories of the SLAM output, each
//    sequence rigidly aligned to the truth (the SLAM frame is its own and
//    some joins of the large run failed), true calibration, landmarks +
//    N(0, 5 cm) per coordinate.
// Prints the problem size, BA wall/CPU time, peak RSS and the image pose
// errors against the truth after an SE(3) (Umeyama) alignment (the SLAM frame
// is its own).
//
//   locforge_spline_ba_kapture_bench --recording DIR --slam DIR [--seeds N] ...  (--help: every option)
// With --align global one rigid transform aligns the whole SLAM output (the
// joins between sequences kept, as a GT run sees them); the perturbation
// turns each camera by D deg about a random axis (its CAD centre kept) and
// scales its focal lengths by 1 +- P % (random sign), image start poses
// turned with it. The last line reports the calibration errors (RMS and max).
#include <sys/resource.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <random>
#include <string>
#include <unordered_map>

#include "locforge/kapture/io.h"
#include "locforge/param_cli.h"
#include "locforge/units.h"
#include "resource_usage.h"
#include "spline_ba.h"
#include "synthetic.h"

namespace {

namespace kp = locforge::kapture;
using locforge::Pose;
using namespace locforge::sfm;

using locforge::sfm::CpuSeconds;
using locforge::sfm::PeakRssMb;

struct Options {
  std::string recording, slam, solver = "auto";
  int seeds = 10, max_track = 10, threads = 2, iterations = 50;
  double intrinsics_scale = 100, min_depth_m = 1.5, max_depth_m = 12, max_angle_deg = 45, pixel_noise_px = 0.5;
  double seconds_per_unit = locforge::kDefaultSecondsPerUnit, sequence_gap_s = 2.0;
  double trajectory_sigma_m = -1, trajectory_sigma_deg = -1;  // < 0: SplineBAOptions defaults
  double pose_sigma_m = -1, pose_sigma_deg = -1;
  bool time_offsets = false, align_trajectories = false;
  std::string align = "sequence";
  double eta = -1, function_tolerance = 1e-6, point_noise_m = 0.05;  // eta < 0: SplineBAOptions' default
  double perturb_focal_percent = 0, perturb_rotation_deg = 0;

  static void Declare(locforge::ParamSchema<Options>& s) {
    using O = Options;
    s.Add("recording", &O::recording, "kapture recording with the true poses (sensors/trajectories.txt)")
        .Required();
    s.Add("slam", &O::slam, "slam/pose_graph output (its rig poses start the splines)").Required();
    s.Add("seeds", &O::seeds, "landmarks seeded per image").Min(1);
    s.Add("max_track", &O::max_track, "longest track kept").Min(2);
    s.Add("threads", &O::threads, "Ceres threads").Min(1);
    s.Add("iterations", &O::iterations, "solver iterations").Min(1);
    s.Add("solver", &O::solver, "linear solver").Choices({"auto", "sparse_schur", "iterative_schur"});
    s.Add("eta", &O::eta, "iterative_schur forcing sequence (< 0: SplineBAOptions')");
    s.Add("function_tolerance", &O::function_tolerance, "Ceres function tolerance").Min(0);
    s.Add("intrinsics_scale", &O::intrinsics_scale, "multiply the recording's intrinsics (1 %-scale recordings)")
        .Min(1e-6);
    s.Add("min_depth_m", &O::min_depth_m, "landmark depth from its seed image, at least").Min(0);
    s.Add("max_depth_m", &O::max_depth_m, "landmark depth at most, and the farthest observing camera").Min(0);
    s.Add("max_angle_deg", &O::max_angle_deg, "largest angle between a landmark's viewing rays").Range(0, 180);
    s.Add("pixel_noise_px", &O::pixel_noise_px, "observation noise per coordinate").Min(0);
    s.Add("point_noise_m", &O::point_noise_m, "start landmarks moved by N(0, sigma^2) per coordinate").Min(0);
    locforge::AddSecondsPerUnit(s, &O::seconds_per_unit);
    s.Add("sequence_gap_s", &O::sequence_gap_s, "a gap this long between rig poses starts a new trajectory")
        .Min(0);
    s.Add("trajectory_sigma_m", &O::trajectory_sigma_m, "spline-to-LiDAR prior (< 0: SplineBAOptions')");
    s.Add("trajectory_sigma_deg", &O::trajectory_sigma_deg, "spline-to-LiDAR prior (< 0: SplineBAOptions')");
    s.Add("pose_sigma_m", &O::pose_sigma_m, "spline pose error of each image (< 0: SplineBAOptions')");
    s.Add("pose_sigma_deg", &O::pose_sigma_deg, "spline pose error of each image (< 0: SplineBAOptions')");
    s.Add("time_offsets", &O::time_offsets, "estimate one clock offset per camera");
    s.Add("align_trajectories", &O::align_trajectories,
          "each sequence but the first may move rigidly (SplineBAOptions)");
    s.Add("align", &O::align, "rigid alignment of the SLAM output to the truth").Choices({"sequence", "global"});
    s.Add("perturb_focal_percent", &O::perturb_focal_percent, "start focal lengths scaled by 1 +- P % (as calib/perturb)")
        .Min(0);
    s.Add("perturb_rotation_deg", &O::perturb_rotation_deg, "start cameras turned by D deg (as calib/perturb)").Min(0);
  }
};

}  // namespace

const char kUsageHead[] =
    "usage: locforge_spline_ba_kapture_bench --recording DIR --slam DIR [options]\n"
    "Time, memory and accuracy of the spline BA on a recording's geometry with synthetic landmarks.\n";

int main(int argc, char** argv) {
  Options o;
  if (const int code = locforge::ParseToolOptions(argc, argv, kUsageHead, &o); code >= 0) return code;
  const auto t_start = std::chrono::steady_clock::now();
  const kp::Sensors sensors = kp::ReadSensors(o.recording + "/sensors/sensors.txt");
  const kp::Rigs rigs = kp::ReadRigs(o.recording + "/sensors/rigs.txt");
  const kp::Trajectories truth_traj = kp::ReadTrajectories(o.recording + "/sensors/trajectories.txt");
  const kp::Trajectories slam_traj = kp::ReadTrajectories(o.slam + "/sensors/trajectories.txt");

  BAProblem truth, init;
  // Platform trajectories: the SLAM rig poses, split at gaps.
  std::vector<std::pair<double, Pose>> rig;  // (seconds, T_world_body)
  for (const auto& [key, pose] : slam_traj.poses)
    if (key.second == "rig") rig.push_back({key.first * o.seconds_per_unit, pose.Inverse()});
  std::sort(rig.begin(), rig.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (size_t i = 0; i < rig.size(); ++i) {
    if (i == 0 || rig[i].first - rig[i - 1].first > o.sequence_gap_s) init.trajectories.emplace_back();
    init.trajectories.back().times_s.push_back(rig[i].first);
    init.trajectories.back().T_world_body.push_back(rig[i].second);
  }
  truth.trajectories = init.trajectories;  // not compared
  // Cameras (intrinsics scaled to full resolution) with their rig extrinsics.
  std::map<std::string, int> sensor_index;
  for (const kp::Sensor& s : sensors.list()) {
    if (!s.IsCamera() || !s.camera) continue;
    const kp::Rig* r = rigs.RigOf(s.id);
    if (!r) continue;
    BAProblem::Sensor bs;
    bs.camera = *s.camera;
    bs.camera.width = static_cast<int>(std::lround(bs.camera.width * o.intrinsics_scale));
    bs.camera.height = static_cast<int>(std::lround(bs.camera.height * o.intrinsics_scale));
    for (double& p : bs.camera.params) p *= o.intrinsics_scale;  // PINHOLE-type: all params are pixels
    bs.T_body_camera = r->Find(s.id)->sensor_from_rig.Inverse();
    sensor_index[s.id] = static_cast<int>(init.sensors.size());
    init.sensors.push_back(bs);
  }
  truth.sensors = init.sensors;
  // Images: every camera pose of the truth that the SLAM output also has.
  for (const auto& [key, pose] : truth_traj.poses) {
    auto si = sensor_index.find(key.second);
    if (si == sensor_index.end()) continue;
    const Pose* start = slam_traj.Find(key.first, key.second);
    if (!start) continue;
    const double t = key.first * o.seconds_per_unit;
    int seq = -1;
    for (size_t k = 0; k < init.trajectories.size(); ++k)
      if (t >= init.trajectories[k].times_s.front() && t <= init.trajectories[k].times_s.back()) seq = static_cast<int>(k);
    if (seq < 0) continue;
    BAProblem::Image im;
    im.trajectory = seq;
    im.sensor = si->second;
    im.time_s = t;
    im.name = key.second + "/" + std::to_string(key.first);
    im.T_world_camera = pose.Inverse();
    truth.images.push_back(im);
    im.T_world_camera = start->Inverse();
    init.images.push_back(im);
  }
  // Landmarks and observations from the true poses.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uni(0, 1);
  std::normal_distribution<double> normal(0, 1);
  const double cell = o.max_depth_m;
  auto cell_of = [&](const Eigen::Vector3d& c) {
    return std::tuple<int, int, int>(std::floor(c.x() / cell), std::floor(c.y() / cell), std::floor(c.z() / cell));
  };
  std::map<std::tuple<int, int, int>, std::vector<int>> grid;
  for (size_t i = 0; i < truth.images.size(); ++i) grid[cell_of(truth.images[i].T_world_camera.t)].push_back(static_cast<int>(i));
  const double cos_max = std::cos(o.max_angle_deg * locforge::kDeg);
  for (size_t i = 0; i < truth.images.size(); ++i) {
    const Pose& Twc = truth.images[i].T_world_camera;
    const locforge::Camera& cam = truth.sensors[truth.images[i].sensor].camera;
    for (int k = 0; k < o.seeds; ++k) {
      const Eigen::Vector2d px(uni(rng) * cam.width, uni(rng) * cam.height);
      const Eigen::Vector3d ray = cam.Unproject(px);
      const double depth = o.min_depth_m + uni(rng) * (o.max_depth_m - o.min_depth_m);
      const Eigen::Vector3d X = Twc * (ray / ray.z() * depth);
      const Eigen::Vector3d seed_dir = (X - Twc.t).normalized();
      std::vector<std::pair<int, Eigen::Vector2d>> track = {{static_cast<int>(i), Eigen::Vector2d()}};
      const auto [cx, cy, cz] = cell_of(X);
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            auto it = grid.find({cx + dx, cy + dy, cz + dz});
            if (it == grid.end()) continue;
            for (int j : it->second) {
              if (j == static_cast<int>(i)) continue;
              const Pose& T = truth.images[j].T_world_camera;
              if ((X - T.t).norm() > o.max_depth_m) continue;
              if ((X - T.t).normalized().dot(seed_dir) < cos_max) continue;
              const Eigen::Vector3d pc = T.Inverse() * X;
              if (pc.z() < 0.3) continue;
              const locforge::Camera& cj = truth.sensors[truth.images[j].sensor].camera;
              const Eigen::Vector2d p = cj.Project(pc);
              if (p.x() < 0 || p.y() < 0 || p.x() >= cj.width || p.y() >= cj.height) continue;
              track.push_back({j, p});
            }
          }
      if (track.size() < 2) continue;
      if (static_cast<int>(track.size()) > o.max_track) {
        std::shuffle(track.begin() + 1, track.end(), rng);
        track.resize(o.max_track);
      }
      track[0].second = cam.Project(Twc.Inverse() * X);
      const int pid = static_cast<int>(truth.points.size());
      truth.points.push_back({X});
      init.points.push_back({X + o.point_noise_m * Eigen::Vector3d(normal(rng), normal(rng), normal(rng))});
      for (const auto& [j, p] : track) {
        const Eigen::Vector2d noisy = p + o.pixel_noise_px * Eigen::Vector2d(normal(rng), normal(rng));
        truth.observations.push_back({j, pid, noisy});
      }
    }
  }
  init.observations = truth.observations;
  // The SLAM output's frame is its own, and on the large run some
  // cross-sequence joins failed (sequences in unrelated frames): align each
  // sequence's SLAM poses (image poses and platform samples) rigidly to the
  // truth (Umeyama on the image centres), keeping the SLAM's drift and noise
  // within the sequence.
  if (o.align != "sequence" && o.align != "global") {
    std::fprintf(stderr, "--align must be sequence or global\n");
    return 2;
  }
  const size_t align_groups = o.align == "global" ? 1 : init.trajectories.size();
  for (size_t k = 0; k < align_groups; ++k) {
    std::vector<int> ids;
    for (size_t i = 0; i < init.images.size(); ++i)
      if (o.align == "global" || init.images[i].trajectory == static_cast<int>(k)) ids.push_back(static_cast<int>(i));
    if (ids.size() < 3) continue;
    Eigen::Matrix3Xd src(3, ids.size()), dst(3, ids.size());
    for (size_t n = 0; n < ids.size(); ++n) {
      src.col(n) = init.images[ids[n]].T_world_camera.t;
      dst.col(n) = truth.images[ids[n]].T_world_camera.t;
    }
    const Pose align = Pose::FromMatrix(Eigen::umeyama(src, dst, false));
    for (int i : ids) init.images[i].T_world_camera = align * init.images[i].T_world_camera;
    for (size_t q = 0; q < init.trajectories.size(); ++q)
      if (o.align == "global" || q == k)
        for (Pose& p : init.trajectories[q].T_world_body) p = align * p;
  }
  // The start calibration moved away from the truth (calib/perturb's model).
  if (o.perturb_focal_percent > 0 || o.perturb_rotation_deg > 0) {
    std::mt19937 prng(11);
    std::vector<Pose> turn(init.sensors.size());
    for (size_t s = 0; s < init.sensors.size(); ++s) {
      const double sign = uni(prng) < 0.5 ? -1 : 1;
      locforge::Camera& cam = init.sensors[s].camera;
      cam.params[0] *= 1 + sign * o.perturb_focal_percent / 100;
      if (cam.model == locforge::CameraModelId::kPinhole || cam.model == locforge::CameraModelId::kOpenCV)
        cam.params[1] *= 1 + sign * o.perturb_focal_percent / 100;
      const Eigen::Vector3d axis = Eigen::Vector3d(normal(prng), normal(prng), normal(prng)).normalized();
      turn[s].q = Eigen::Quaterniond(Eigen::AngleAxisd(o.perturb_rotation_deg * M_PI / 180, axis));
      init.sensors[s].T_body_camera.q = (init.sensors[s].T_body_camera.q * turn[s].q).normalized();
    }
    for (auto& im : init.images) im.T_world_camera = im.T_world_camera * turn[im.sensor];
  }
  const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  const double rss_problem = PeakRssMb();

  SplineBAOptions options;
  options.num_threads = o.threads;
  options.max_iterations = o.iterations;
  options.linear_solver = o.solver;
  if (o.trajectory_sigma_m >= 0) options.trajectory_prior_sigma_translation_m = o.trajectory_sigma_m;
  if (o.trajectory_sigma_deg >= 0) options.trajectory_prior_sigma_rotation_rad = locforge::DegreesToRadians(o.trajectory_sigma_deg);
  if (o.pose_sigma_m > 0) options.prior_sigma_translation_m = o.pose_sigma_m;
  if (o.pose_sigma_deg > 0) options.prior_sigma_rotation_rad = locforge::DegreesToRadians(o.pose_sigma_deg);
  options.estimate_time_offsets = o.time_offsets;
  options.align_trajectories = o.align_trajectories;
  if (o.eta > 0) options.iterative_eta = o.eta;
  options.function_tolerance = o.function_tolerance;
  if (!options.Check()) {
    std::fprintf(stderr, "%s\n", options.CheckMessage().c_str());
    return 2;
  }
  const SceneErrors e0 = CompareToTruth(init, truth);
  BAProblem problem = init;
  const double cpu0 = CpuSeconds();
  const SplineBAResult r = RunSplineBA(options, &problem);
  const double ba_cpu = CpuSeconds() - cpu0;
  const SceneErrors e = CompareToTruth(problem, truth);
  std::printf("trajectories %zu, cameras %zu, images %zu, points %zu, observations %zu (%.1f per image, %.2f per point)\n",
              problem.trajectories.size(), problem.sensors.size(), problem.images.size(), problem.points.size(),
              problem.observations.size(), double(problem.observations.size()) / problem.images.size(),
              double(problem.observations.size()) / problem.points.size());
  std::printf("| images | points | observations | solver | threads | build s | BA wall s | BA CPU s | iterations | reproj px (initial -> final) | "
              "image poses SE(3)-aligned RMS cm / deg (start -> final) | peak RSS MB (after build -> after BA) |\n"
              "|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::printf("| %zu | %zu | %zu | %s | %d | %.1f | %.1f | %.1f | %d%s | %.2f -> %.3f | %.2f / %.3f -> %.2f / %.3f | %.0f -> %.0f |\n",
              problem.images.size(), problem.points.size(), problem.observations.size(), o.solver.c_str(), o.threads,
              build_s, r.seconds, ba_cpu, r.iterations, r.converged ? "" : " (limit)", r.initial_mean_reproj_px,
              r.final_mean_reproj_px, 100 * e0.aligned_position_rms_m, e0.aligned_rotation_rms_deg,
              100 * e.aligned_position_rms_m, e.aligned_rotation_rms_deg, rss_problem, PeakRssMb());
  std::printf("focal max error %.4f %%, camera rotation max error %.4f deg\nsolver: %s\n", 100 * e.focal_max_rel,
              e.extrinsic_rotation_max_deg, r.message.c_str());
  // Calibration errors against the truth: RMS over the sensors.
  double focal2 = 0, rot2 = 0;
  for (size_t s = 0; s < problem.sensors.size(); ++s) {
    const double fe = problem.sensors[s].camera.params[0] / truth.sensors[s].camera.params[0] - 1;
    focal2 += fe * fe;
    const double re = problem.sensors[s].T_body_camera.q.angularDistance(truth.sensors[s].T_body_camera.q) * 180 / M_PI;
    rot2 += re * re;
  }
  const double ns = std::max<size_t>(1, problem.sensors.size());
  std::printf("calibration: focal RMS %.4f %%, camera rotation RMS %.4f deg; image poses SE(3)-aligned %.3f cm / %.4f deg\n",
              100 * std::sqrt(focal2 / ns), std::sqrt(rot2 / ns), 100 * e.aligned_position_rms_m, e.aligned_rotation_rms_deg);
  std::printf("image centres Sim(3)-aligned: scale - 1 %.4f %% -> %.4f %%, residual %.3f cm -> %.3f cm\n",
              100 * e0.similarity_scale_minus_1, 100 * e.similarity_scale_minus_1,
              100 * e0.similarity_position_rms_m, 100 * e.similarity_position_rms_m);
  return r.usable ? 0 : 1;
}

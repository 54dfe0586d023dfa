#include "synthetic.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>

#include "locforge/units.h"

namespace locforge::sfm {

namespace {

Eigen::Quaterniond Rot(const Eigen::Vector3d& axis, double angle) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized()));
}

// True platform pose of sequence k at time t (seconds from the sequence
// start): arcs of an ellipse, heading along the velocity, small roll/pitch.
struct Motion {
  double a, b, omega, theta0, phase;
  Pose At(double t) const {
    const double th = theta0 + omega * t;
    const Eigen::Vector3d p(a * std::cos(th), b * std::sin(th), 0.02 * std::sin(2.0 * t + phase));
    const double yaw = std::atan2(b * std::cos(th), -a * std::sin(th));
    const Eigen::Quaterniond q = Rot(Eigen::Vector3d::UnitZ(), yaw) *
                                 Rot(Eigen::Vector3d::UnitY(), 0.01 * std::sin(0.7 * t + phase)) *
                                 Rot(Eigen::Vector3d::UnitX(), 0.01 * std::sin(1.3 * t + 2 * phase));
    return Pose(q, p);
  }
};

Eigen::Vector3d RandomUnit(std::mt19937& rng) {
  std::normal_distribution<double> n(0, 1);
  return Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
}

// The truth and the initial problem of one scene, drawn from one random
// stream in a fixed order (the draws' order is the scene: keep it).
struct SceneMaker {
  explicit SceneMaker(const SyntheticOptions& o) : o(o), rng(o.seed), normal(0, 1), uniform(0, 1) {}

  const SyntheticOptions& o;
  std::mt19937 rng;
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform;
  SyntheticScene scene;
  BAProblem& truth = scene.truth;
  BAProblem& init = scene.initial;
  double a = 0, b = 0;  // the ellipse's half axes
  std::vector<Motion> motions;
  std::vector<double> rates, offsets;  // by camera: images per second, clock offset

  static double SequenceT0(int k) { return 1000.0 * k; }  // each sequence on its own clock range

  // Ellipse sized so that every sequence covers ~2 rad at the given speed.
  void MakeMotions() {
    const double path = o.speed_mps * o.duration_s;
    a = std::max(6.0, path / 2.0 / 1.3), b = 0.6 * a;
    const double omega = o.speed_mps / (0.8 * a);
    for (int k = 0; k < o.sequences; ++k) motions.push_back({a, b, omega, 0.5 * omega * o.duration_s * k, 0.9 * k});
  }

  // Camera c: industrial (even c) or smartphone (odd c), models in turn,
  // looking outwards at yaw 2 pi c / cameras, 10 deg down.
  static BAProblem::Sensor TrueCamera(int c, int cameras) {
    const Eigen::Matrix3d R0 = (Eigen::Matrix3d() << 0, 0, 1, -1, 0, 0, 0, -1, 0).finished();
    const CameraModelId models[] = {CameraModelId::kPinhole, CameraModelId::kSimpleRadial, CameraModelId::kOpenCV,
                                    CameraModelId::kRadial, CameraModelId::kSimplePinhole};
    const bool phone = c % 2 == 1;
    const int w = phone ? 540 : 648, h = phone ? 720 : 512;
    const double f = 0.5 * std::hypot(w, h) / std::tan(0.5 * (phone ? 77.0 : 95.0) * kDeg);
    Camera cam;
    cam.model = models[c % 5];
    cam.width = w;
    cam.height = h;
    switch (cam.model) {
      case CameraModelId::kPinhole: cam.params = {f, f * 1.002, w / 2.0 + 3, h / 2.0 - 2}; break;
      case CameraModelId::kSimpleRadial: cam.params = {f, w / 2.0, h / 2.0, -0.04}; break;
      case CameraModelId::kOpenCV: cam.params = {f, f, w / 2.0 - 1, h / 2.0 + 2, -0.05, 0.01, 0.001, -0.0005}; break;
      case CameraModelId::kRadial: cam.params = {f, w / 2.0, h / 2.0, -0.03, 0.005}; break;
      default: cam.params = {f, w / 2.0, h / 2.0}; break;
    }
    const double yaw = 2 * M_PI * c / cameras;
    const Eigen::Quaterniond q_bc(Rot(Eigen::Vector3d::UnitZ(), yaw) * Rot(Eigen::Vector3d::UnitY(), -10 * kDeg) *
                                  Eigen::Quaterniond(R0));
    const Eigen::Vector3d t_bc = Rot(Eigen::Vector3d::UnitZ(), yaw) * Eigen::Vector3d(0.25, 0, 0) +
                                 Eigen::Vector3d(0, 0, phone ? 1.70 : 1.55);
    BAProblem::Sensor s;
    s.camera = cam;
    s.T_body_camera = Pose(q_bc, t_bc);
    return s;
  }

  // The calibration the adjustment starts from: focal lengths scaled, the
  // principal point moved, the rotation turned.
  BAProblem::Sensor PerturbedCamera(const BAProblem::Sensor& s) {
    BAProblem::Sensor p = s;
    const double sign = uniform(rng) < 0.5 ? -1 : 1;
    const bool two_focals = s.camera.model == CameraModelId::kPinhole || s.camera.model == CameraModelId::kOpenCV;
    const int pp = two_focals ? 2 : 1;
    p.camera.params[0] *= 1 + sign * o.focal_perturbation;
    if (two_focals) p.camera.params[1] *= 1 + sign * o.focal_perturbation;
    p.camera.params[pp] += o.principal_point_perturbation_px * normal(rng);
    p.camera.params[pp + 1] += o.principal_point_perturbation_px * normal(rng);
    p.T_body_camera.q = (Rot(RandomUnit(rng), o.rotation_perturbation_deg * kDeg) * s.T_body_camera.q).normalized();
    return p;
  }

  void AddCameras() {
    for (int c = 0; c < o.cameras; ++c) {
      const bool phone = c % 2 == 1;
      const BAProblem::Sensor s = TrueCamera(c, o.cameras);
      truth.sensors.push_back(s);
      init.sensors.push_back(PerturbedCamera(s));
      rates.push_back(phone ? 1.0 : 2.5);
      offsets.push_back(o.clock_offset_sigma_s * normal(rng));
    }
  }

  // Sequence k's true trajectory and LiDAR-like samples at 10 Hz, 1 s beyond
  // the images: smooth errors (two sines per axis) plus white noise.
  void AddTrajectory(int k) {
    BAProblem::Trajectory tt, ti;
    Eigen::Vector3d amp_p[2], amp_r[2], freq, ph;
    for (int j = 0; j < 2; ++j) {
      amp_p[j] = RandomUnit(rng) * o.lidar_smooth_m / std::sqrt(2.0);
      amp_r[j] = RandomUnit(rng) * o.lidar_smooth_deg * kDeg / std::sqrt(2.0);
    }
    for (int j = 0; j < 3; ++j) {
      freq(j) = 2 * M_PI / (3.0 + 6.0 * uniform(rng));
      ph(j) = 2 * M_PI * uniform(rng);
    }
    for (double t = -1.0; t <= o.duration_s + 1.0 + 1e-9; t += 0.1) {
      const Pose T = motions[k].At(t);
      tt.times_s.push_back(SequenceT0(k) + t);
      tt.T_world_body.push_back(T);
      const double s1 = std::sin(freq(0) * t + ph(0)), s2 = std::sin(freq(1) * t + ph(1));
      const Eigen::Vector3d dp = amp_p[0] * s1 + amp_p[1] * s2 +
                                 o.lidar_white_m / std::sqrt(3.0) * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
      const Eigen::Vector3d dr = amp_r[0] * s2 + amp_r[1] * std::sin(freq(2) * t + ph(2)) +
                                 o.lidar_white_deg * kDeg / std::sqrt(3.0) *
                                     Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
      ti.times_s.push_back(SequenceT0(k) + t);
      ti.T_world_body.push_back(Pose(T.q * ExpSO3(dr), T.t + dp));
    }
    truth.trajectories.push_back(tt);
    init.trajectories.push_back(ti);
  }

  // Images: nominal triggers per camera, true capture = nominal + jitter,
  // timestamp = nominal + clock offset.
  void AddImages(int k) {
    const auto& lidar = init.trajectories[k];
    for (int c = 0; c < o.cameras; ++c) {
      const double phase = uniform(rng) / rates[c];
      for (double nominal = phase; nominal < o.duration_s; nominal += 1.0 / rates[c]) {
        const double capture = nominal + o.jitter_sigma_s * normal(rng);
        BAProblem::Image im;
        im.trajectory = k;
        im.sensor = c;
        im.time_s = SequenceT0(k) + nominal + offsets[c];
        im.name = "seq" + std::to_string(k) + "/cam" + std::to_string(c) + "/" + std::to_string(truth.images.size());
        im.T_world_camera = motions[k].At(capture) * truth.sensors[c].T_body_camera;
        truth.images.push_back(im);
        // Initial: the LiDAR trajectory interpolated at the timestamp.
        const double tl = im.time_s - SequenceT0(k);
        const size_t i0 = std::clamp<size_t>(static_cast<size_t>((tl + 1.0) / 0.1), 0, lidar.times_s.size() - 2);
        const double alpha = (im.time_s - lidar.times_s[i0]) / (lidar.times_s[i0 + 1] - lidar.times_s[i0]);
        im.T_world_camera = Interpolate(lidar.T_world_body[i0], lidar.T_world_body[i0 + 1], alpha) *
                            init.sensors[c].T_body_camera;
        init.images.push_back(im);
        scene.capture_time_s.push_back(SequenceT0(k) + capture);
      }
    }
  }

  // Wall points of the room around the ellipse (4 walls, z in [0, H] m),
  // floor and ceiling (sparser), and pillars (1 m square, full height) inside
  // and outside the ellipse: depth variety that conditions the calibration.
  std::vector<Eigen::Vector3d> CandidatePoints() {
    const double X = a + 6, Y = b + 6, H = 4;
    const int nx = static_cast<int>(o.points_per_m2 * 2 * X * H), ny = static_cast<int>(o.points_per_m2 * 2 * Y * H);
    std::vector<Eigen::Vector3d> candidates;
    for (int side = 0; side < 2; ++side) {
      for (int i = 0; i < nx; ++i)
        candidates.emplace_back((2 * uniform(rng) - 1) * X, side ? Y : -Y, H * uniform(rng));
      for (int i = 0; i < ny; ++i)
        candidates.emplace_back(side ? X : -X, (2 * uniform(rng) - 1) * Y, H * uniform(rng));
    }
    const int nf = static_cast<int>(0.25 * o.points_per_m2 * 4 * X * Y);
    for (int i = 0; i < nf; ++i)
      candidates.emplace_back((2 * uniform(rng) - 1) * X, (2 * uniform(rng) - 1) * Y, i % 2 ? 0.0 : H);
    for (int p = 0; p < 12; ++p) {
      const double ang = 2 * M_PI * p / 12, rad = p % 2 ? 0.6 : 1.25;
      const Eigen::Vector2d c(rad * a * std::cos(ang), rad * b * std::sin(ang));
      for (int i = 0; i < static_cast<int>(o.points_per_m2 * 4 * H); ++i) {
        const double s = 2 * uniform(rng) - 1;
        const int face = i % 4;
        const Eigen::Vector2d off = face == 0 ? Eigen::Vector2d(0.5, 0.5 * s) : face == 1 ? Eigen::Vector2d(-0.5, 0.5 * s)
                                    : face == 2 ? Eigen::Vector2d(0.5 * s, 0.5) : Eigen::Vector2d(0.5 * s, -0.5);
        candidates.emplace_back(c.x() + off.x(), c.y() + off.y(), H * uniform(rng));
      }
    }
    return candidates;
  }

  // The candidates seen by at least min_track_length images (in front,
  // within max_depth_m and the image), with their noisy observations.
  void AddPoints(const std::vector<Eigen::Vector3d>& candidates) {
    for (const Eigen::Vector3d& P : candidates) {
      std::vector<BAProblem::Observation> obs;
      for (size_t i = 0; i < truth.images.size(); ++i) {
        const auto& im = truth.images[i];
        const Camera& cam = truth.sensors[im.sensor].camera;
        const Eigen::Vector3d pc = im.T_world_camera.Inverse() * P;
        if (pc.z() < 0.5 || pc.z() > o.max_depth_m || pc.head<2>().norm() > 1.5 * pc.z()) continue;
        const Eigen::Vector2d xy = cam.Project(pc);
        if (xy.x() < 0 || xy.y() < 0 || xy.x() > cam.width || xy.y() > cam.height) continue;
        const Eigen::Vector2d noise(normal(rng), normal(rng));
        obs.push_back({static_cast<int>(i), static_cast<int>(truth.points.size()), xy + o.pixel_noise_px * noise});
      }
      if (static_cast<int>(obs.size()) < o.min_track_length) continue;
      truth.points.push_back({P});
      init.points.push_back({P + o.point_noise_m * Eigen::Vector3d(normal(rng), normal(rng), normal(rng))});
      truth.observations.insert(truth.observations.end(), obs.begin(), obs.end());
    }
    init.observations = truth.observations;
  }
};

}  // namespace

SyntheticScene MakeSyntheticScene(const SyntheticOptions& o) {
  SceneMaker m(o);
  m.MakeMotions();
  m.AddCameras();
  for (int k = 0; k < o.sequences; ++k) m.AddTrajectory(k);
  for (int k = 0; k < o.sequences; ++k) m.AddImages(k);
  m.AddPoints(m.CandidatePoints());
  return std::move(m.scene);
}

SyntheticOptions TestSceneOptions() {
  SyntheticOptions o;
  o.clock_offset_sigma_s = 0.003;
  return o;
}

SplineBAOptions SyntheticSceneBAOptions() {
  SplineBAOptions options;
  options.knot_spacing_s = 0.1;
  options.prior_sigma_rotation_rad = 0.002;
  options.prior_sigma_translation_m = 0.01;
  options.trajectory_prior_sigma_rotation_rad = 0.02;
  options.trajectory_prior_sigma_translation_m = 0.05;
  options.align_trajectories = false;
  options.alignment_sigma_rotation_rad = 0.05;
  options.cauchy_scale_px = 1.0;
  options.max_iterations = 100;
  return options;
}

SceneErrors CompareToTruth(const BAProblem& est, const BAProblem& truth) {
  SceneErrors e;
  double sp = 0, sr = 0;
  for (size_t i = 0; i < truth.images.size(); ++i) {
    sp += (est.images[i].T_world_camera.t - truth.images[i].T_world_camera.t).squaredNorm();
    const double r = RotationAngleDeg(est.images[i].T_world_camera.q, truth.images[i].T_world_camera.q);
    sr += r * r;
  }
  const size_t ni = truth.images.size();
  if (ni) {
    e.position_rms_m = std::sqrt(sp / ni);
    e.rotation_rms_deg = std::sqrt(sr / ni);
  }
  if (ni >= 3) {
    Eigen::Matrix3Xd src(3, ni), dst(3, ni);
    for (size_t i = 0; i < ni; ++i) {
      src.col(i) = est.images[i].T_world_camera.t;
      dst.col(i) = truth.images[i].T_world_camera.t;
    }
    const Eigen::Matrix4d A = Eigen::umeyama(src, dst, false);
    const Pose align = Pose::FromMatrix(A);
    double ap = 0, ar = 0;
    for (size_t i = 0; i < ni; ++i) {
      const Pose aligned = align * est.images[i].T_world_camera;
      ap += (aligned.t - truth.images[i].T_world_camera.t).squaredNorm();
      const double r = RotationAngleDeg(aligned.q, truth.images[i].T_world_camera.q);
      ar += r * r;
    }
    e.aligned_position_rms_m = std::sqrt(ap / ni);
    e.aligned_rotation_rms_deg = std::sqrt(ar / ni);
    const Eigen::Matrix4d S = Eigen::umeyama(src, dst, true);
    e.similarity_scale_minus_1 = S.block<3, 1>(0, 0).norm() - 1;
    double sp2 = 0;
    for (size_t i = 0; i < ni; ++i)
      sp2 += (S.block<3, 3>(0, 0) * src.col(i) + S.block<3, 1>(0, 3) - dst.col(i)).squaredNorm();
    e.similarity_position_rms_m = std::sqrt(sp2 / ni);
  }
  for (size_t s = 0; s < truth.sensors.size(); ++s) {
    const Camera& a = est.sensors[s].camera;
    const Camera& b = truth.sensors[s].camera;
    e.focal_max_rel = std::max({e.focal_max_rel, std::abs(a.fx() / b.fx() - 1), std::abs(a.fy() / b.fy() - 1)});
    e.extrinsic_rotation_max_deg = std::max(
        e.extrinsic_rotation_max_deg, RotationAngleDeg(est.sensors[s].T_body_camera.q, truth.sensors[s].T_body_camera.q));
  }
  double st = 0;
  size_t n = 0;
  for (size_t k = 0; k < truth.trajectories.size(); ++k)
    for (size_t i = 0; i < truth.trajectories[k].times_s.size(); ++i, ++n)
      st += (est.trajectories[k].T_world_body[i].t - truth.trajectories[k].T_world_body[i].t).squaredNorm();
  if (n) e.trajectory_position_rms_m = std::sqrt(st / n);
  return e;
}

}  // namespace locforge::sfm

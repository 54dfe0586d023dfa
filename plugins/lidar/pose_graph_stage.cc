// slam/pose_graph: keyframes of undistorted scans, sequential registration
// edges (odometry as the initial guess), coarse-to-fine loop closures
// (distance + travelled-distance candidates, rough check on downsampled
// clouds, precise registration), Ceres on SE(3) with robust loop edges;
// several sequences join one graph through cross-sequence loops.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>
#include <sstream>

#include "cloud.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"
#include "locforge/registration.h"
#include "plot.h"
#include "pose_graph.h"
#include "stages.h"

namespace locforge::lidar {

void PoseGraphSlamOptions::Declare(ParamSchema<PoseGraphSlamOptions>& s) {
  using O = PoseGraphSlamOptions;
  s.Add("dataset", &O::dataset,
        "Kapture recording (wheel records, rigs, camera records); required with motion_prior wheel").Path();
  s.Add("motion_prior", &O::motion_prior,
        "Initial guess of sequential registrations: wheel odometry, or constant velocity (no odometry; "
        "every scan a keyframe)").Choices({"wheel", "constant_velocity"});
  s.Add("max_scan_gap", &O::max_scan_gap,
        "constant_velocity: a larger time gap between scans starts a new segment (s)").Min(1e-6);
  s.Add("max_guess_deviation", &O::max_guess_deviation,
        "A sequential registration farther than this from its guess failed (m)").Min(0);
  s.Add("registration", &O::registration, "Registration back-end (stage id of a component)");
  s.Add("registration_params", &O::registration_params, "key=value parameters of the back-end");
  s.Add("keyframe_distance", &O::keyframe_distance, "Travel between keyframes (m)").Range(0, 100);
  s.Add("keyframe_angle", &O::keyframe_angle, "Rotation between keyframes (deg)").Range(0, 360);
  s.Add("min_overlap", &O::min_overlap, "Inlier fraction needed by a sequential edge").Range(0, 1);
  s.Add("loop_radius", &O::loop_radius, "Distance of loop candidates (m)").Min(0);
  s.Add("loop_min_travel", &O::loop_min_travel, "Travel since a same-sequence loop candidate (m)").Min(0);
  s.Add("loop_rough_voxel", &O::loop_rough_voxel, "Voxel of the rough loop check (m)").Range(0.01, 10);
  s.Add("loop_rough_overlap", &O::loop_rough_overlap, "Inlier fraction of the rough check").Range(0, 1);
  s.Add("loop_rough_error", &O::loop_rough_error, "Largest mean residual of the rough check (m)").Min(0);
  s.Add("loop_overlap", &O::loop_overlap, "Inlier fraction of the precise loop check").Range(0, 1);
  s.Add("loop_yaw_hypotheses", &O::loop_yaw_hypotheses,
        "Headings tried by the rough check between sequences not yet joined").Range(1, 72);
  s.Add("loop_stride", &O::loop_stride, "Search loops from every n-th keyframe").Range(1, 1000);
  s.Add("loss", &O::loss, "Robust loss of loop edges").Choices({"cauchy", "huber", "none"});
  s.Add("loss_scale", &O::loss_scale, "Robust loss scale (whitened residual units)").Min(1e-6);
  s.Add("edge_information", &O::edge_information,
        "Information of registration edges: the back-end's Hessian rescaled to the sigmas (registration) "
        "or diagonal from the sigmas (fixed)").Choices({"registration", "fixed"});
  s.Add("information_max_ratio", &O::information_max_ratio,
        "edge_information registration: weakest direction at most this many sigmas").Range(1, 1e6);
  s.Add("sigma_translation", &O::sigma_translation,
        "Std of registration edges (m; their best-constrained direction with edge_information registration)")
      .Min(1e-6);
  s.Add("sigma_rotation", &O::sigma_rotation, "Std of registration edges (deg; likewise)").Min(1e-6);
  s.Add("odometry_sigma", &O::odometry_sigma,
        "Std of odometry edges per metre driven (m/m); 0: no odometry edges").Min(0);
  s.Add("odometry_sigma_rotation", &O::odometry_sigma_rotation,
        "Rotation std of odometry edges per metre driven (deg/m)").Min(1e-6);
  s.Add("planar", &O::planar, "Level-floor prior: heights and tilts held near the first pose's");
  s.Add("planar_sigma_z", &O::planar_sigma_z, "Height std of the planar prior (m)").Min(1e-6);
  s.Add("planar_sigma_tilt", &O::planar_sigma_tilt, "Tilt std of the planar prior (deg)").Min(1e-6);
  s.Add("rounds", &O::rounds, "Loop search + optimisation rounds").Range(1, 20);
  s.Add("map_voxel", &O::map_voxel, "Voxel of the accumulated map (m)").Range(0.005, 10);
  s.Add("map_residual_k", &O::map_residual_k,
        "Neighbours of the map's point-to-plane residual (slam.json map_plane_residual)").Range(3, 100);
  s.Add("map_residual_radius", &O::map_residual_radius, "Neighbour search radius of that residual (m)")
      .Range(0.01, 10);
  s.Add("initial_poses", &O::initial_poses,
        "Manual initial-pose corrections, one 'sequence x y yaw_deg' per entry");
  s.Add("seconds_per_unit", &O::seconds_per_unit, "Duration of one timestamp unit (s)").Range(1e-12, 1);
  LOCFORGE_LIDAR_WHEEL_PARAMS(O);
}

bool PoseGraphSlamOptions::Check(std::string* why) const {
  for (const auto& p : initial_poses) {
    std::istringstream s(p);
    std::string seq;
    double x, y, yaw;
    if (!(s >> seq >> x >> y >> yaw)) {
      if (why) *why = "initial_poses: '" + p + "' is not 'sequence x y yaw_deg'";
      return false;
    }
  }
  for (const auto& p : registration_params)
    if (p.find('=') == std::string::npos) {
      if (why) *why = "registration_params: '" + p + "' is not key=value";
      return false;
    }
  return true;
}

namespace {

struct Keyframe {
  int id = 0;
  Timestamp timestamp = 0;
  std::string sequence;
  Cloud cloud, rough;
  double travelled = 0;  // distance since the sequence start (m): odometry, or estimated
};

// "undistorted/<seq>/..." -> "<seq>"; paths without a folder -> "".
std::string SequenceOfScan(const std::string& path) {
  std::vector<std::string> parts;
  for (const auto& c : fs::path(path)) parts.push_back(c.generic_string());
  size_t i = (!parts.empty() && parts[0] == "undistorted") ? 1 : 0;
  return parts.size() >= i + 2 ? parts[i] : std::string();
}

Matrix6d DiagonalInformation(double sigma_t, double sigma_r_rad) {
  Vector6d d;
  d << Eigen::Vector3d::Constant(1 / (sigma_t * sigma_t)), Eigen::Vector3d::Constant(1 / (sigma_r_rad * sigma_r_rad));
  return d.asDiagonal();
}

class Slam {
 public:
  Slam(const PoseGraphSlamOptions& o, RunContext& ctx)
      : o_(o), ctx_(ctx), backend_(MakeBackend(o, ctx)) {
    if (o.motion_prior == "wheel" && o.dataset.empty())
      throw ParamError("slam/pose_graph: dataset is required with motion_prior wheel (the wheel records)");
    if (o.motion_prior == "wheel")
      odometry_ = std::make_unique<WheelOdometry>(WheelOdometry::FromKapture(o.dataset, o.Wheels()));
  }

  void Run();

 private:
  static RegistrationBackend MakeBackend(const PoseGraphSlamOptions& o, RunContext& ctx) {
    std::vector<std::pair<std::string, std::string>> params;
    for (const auto& kv : o.registration_params) {
      const size_t eq = kv.find('=');
      params.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
    }
    return RegistrationBackend::Create(ctx, o.registration, params);
  }
  void SelectKeyframes(const std::vector<kapture::DataRecord>& scans, const fs::path& scans_root);
  void AddSequentialEdges();
  int AddLoopEdges();
  bool TryLoop(const Keyframe& a, const Keyframe& b);
  // Same sequence and motion segment (odometry segment, or no gap above max_scan_gap).
  bool SameSegment(const Keyframe& a, Timestamp t, const std::string& sequence) const;
  Pose MotionGuess(size_t i) const;
  Matrix6d EdgeInformation(const RegistrationResult& r, const Pose& T_ab) const;
  Pose PoseAt(Timestamp t, bool* found) const;
  void WriteOutputs(const std::vector<kapture::DataRecord>& scans, const PoseGraph& before,
                    const PoseGraphSummary& summary, double seconds);

  const PoseGraphSlamOptions& o_;
  RunContext& ctx_;
  std::unique_ptr<WheelOdometry> odometry_;  // null with motion_prior constant_velocity
  RegistrationBackend backend_;
  std::vector<Keyframe> keyframes_;  // sequences in time order, each in time order
  PoseGraph graph_;
  std::set<std::pair<int, int>> accepted_;  // loop edges added
  int64_t loop_tests_ = 0;
  std::set<std::pair<std::string, std::string>> joined_;  // sequences joined by a loop
  int sequential_fallbacks_ = 0;
  int information_fallbacks_ = 0;  // registration information unusable: fixed sigmas used
  std::map<std::string, Pose> start_poses_;
};

void Slam::SelectKeyframes(const std::vector<kapture::DataRecord>& scans, const fs::path& scans_root) {
  const double max_angle = o_.keyframe_angle * M_PI / 180;
  std::map<std::string, Pose> corrections;
  for (const auto& p : o_.initial_poses) {
    std::istringstream s(p);
    std::string seq;
    double x, y, yaw;
    s >> seq >> x >> y >> yaw;
    corrections[seq] = Pose(Eigen::Quaterniond(Eigen::AngleAxisd(yaw * M_PI / 180, Eigen::Vector3d::UnitZ())),
                            Eigen::Vector3d(x, y, 0));
  }
  kapture::Kapture k(scans_root);
  const Keyframe* last = nullptr;
  for (const auto& r : scans) {
    const double t = static_cast<double>(r.timestamp);
    if (odometry_ && !odometry_->Covers(t)) continue;
    const std::string seq = SequenceOfScan(r.path);
    const bool new_sequence = !last || !SameSegment(*last, r.timestamp, seq);
    double travelled = 0;
    if (!new_sequence && odometry_) {
      const Pose rel = odometry_->Relative(last->timestamp, t);
      const double angle = Eigen::AngleAxisd(rel.q).angle();
      if (rel.t.norm() < o_.keyframe_distance && angle < max_angle) continue;
      travelled = last->travelled + odometry_->Distance(last->timestamp, t);
    }
    Keyframe kf;
    kf.id = static_cast<int>(keyframes_.size());
    kf.timestamp = r.timestamp;
    kf.sequence = seq;
    kf.travelled = travelled;
    kf.cloud = ReadScan(k.ExistingRecordDataPath(r.path, "sensors/records_lidar.txt"));
    kf.rough = VoxelDownsample(kf.cloud, o_.loop_rough_voxel);
    // Initial pose: sequence start (identity, or the manual correction) x
    // odometry (constant velocity: chained by the sequential registrations).
    if (new_sequence) {
      const auto c = corrections.find(seq);
      if (!start_poses_.count(seq)) start_poses_[seq] = c != corrections.end() ? c->second : Pose();
      graph_.nodes[kf.id] = start_poses_[seq];
    } else {
      graph_.nodes[kf.id] = graph_.nodes[last->id] * (odometry_ ? odometry_->Relative(last->timestamp, t) : Pose());
    }
    keyframes_.push_back(std::move(kf));
    last = &keyframes_.back();
  }
  if (keyframes_.empty())
    throw InputError(scans_root.string(), 0, "records_lidar", odometry_ ? "no scan covered by odometry" : "no scan");
  graph_.fixed = {0};
  if (o_.planar) {
    graph_.planar_sigma_z = o_.planar_sigma_z;
    graph_.planar_sigma_tilt = o_.planar_sigma_tilt * M_PI / 180;
  }
}

bool Slam::SameSegment(const Keyframe& a, Timestamp t, const std::string& sequence) const {
  if (a.sequence != sequence) return false;
  if (odometry_) return odometry_->SameSegment(static_cast<double>(a.timestamp), static_cast<double>(t));
  return std::abs(static_cast<double>(t - a.timestamp)) * o_.seconds_per_unit <= o_.max_scan_gap;
}

// Guess of T_{i-1,i}: wheel odometry, or constant velocity: the previous
// keyframe step's twist xi = Log(T_{i-2,i-1}) scaled by the ratio of the time
// steps (identity at a segment's start).
Pose Slam::MotionGuess(size_t i) const {
  const Keyframe& a = keyframes_[i - 1];
  const Keyframe& b = keyframes_[i];
  if (odometry_) return odometry_->Relative(static_cast<double>(a.timestamp), static_cast<double>(b.timestamp));
  if (i < 2 || !SameSegment(keyframes_[i - 2], a.timestamp, a.sequence)) return Pose();
  const Keyframe& z = keyframes_[i - 2];
  const Pose previous = graph_.nodes.at(z.id).Inverse() * graph_.nodes.at(a.id);
  const double ratio = static_cast<double>(b.timestamp - a.timestamp) / std::max<double>(1, a.timestamp - z.timestamp);
  return ExpSE3(LogSE3(previous) * ratio);
}

// Information of a registration edge (header of PoseGraphSlamOptions): the
// back-end's Hessian in the edge's coordinates, rescaled; fixed sigmas when
// asked for or when the Hessian is unusable.
Matrix6d Slam::EdgeInformation(const RegistrationResult& r, const Pose& T_ab) const {
  const double sigma_r = o_.sigma_rotation * M_PI / 180;
  const Matrix6d fixed = DiagonalInformation(o_.sigma_translation, sigma_r);
  if (o_.edge_information == "fixed") return fixed;
  Matrix6d out;
  if (!NormalizeInformation(RegistrationInformationToEdge(r.information, T_ab), o_.sigma_translation, sigma_r,
                            o_.information_max_ratio, &out)) {
    ++const_cast<Slam*>(this)->information_fallbacks_;
    return fixed;
  }
  return out;
}

void Slam::AddSequentialEdges() {
  const Matrix6d odo_info = DiagonalInformation(5 * o_.sigma_translation, 5 * o_.sigma_rotation * M_PI / 180);
  for (size_t i = 1; i < keyframes_.size(); ++i) {
    ctx_.ThrowIfCancelled();
    const Keyframe& a = keyframes_[i - 1];
    Keyframe& b = keyframes_[i];
    if (!SameSegment(a, b.timestamp, b.sequence)) continue;
    // Constant velocity mispredicts sudden turns and stops: the zero-motion
    // guess is tried too (the better-overlapping accepted result is kept),
    // then, when both fail, headings around the guess.
    std::vector<Pose> guesses = {MotionGuess(i)};
    if (!odometry_ && (guesses[0].t.norm() > 0.05 || Eigen::AngleAxisd(guesses[0].q).angle() > 0.05))
      guesses.push_back(Pose());
    Pose guess = guesses[0];
    RegistrationResult r;
    bool ok = false;
    auto try_guesses = [&](const std::vector<Pose>& candidates) {
      for (const Pose& g : candidates) {
        const RegistrationResult c = backend_.Align(b.cloud, a.cloud, g, ctx_.threads());
        const bool c_ok = c.converged && c.inlier_fraction >= o_.min_overlap &&
                          (c.T_target_source.t - g.t).norm() < o_.max_guess_deviation;
        if (c_ok && (!ok || c.inlier_fraction > r.inlier_fraction)) {
          r = c;
          guess = g;
          ok = true;
        }
      }
    };
    try_guesses(guesses);
    if (!ok && !odometry_) {
      // A turn faster than the prior knows: headings around the guess, as when
      // joining sequences (loop_yaw_hypotheses of them).
      std::vector<Pose> turned;
      for (int h = 1; h < o_.loop_yaw_hypotheses; ++h)
        turned.push_back(guesses[0] * Pose(Eigen::Quaterniond(Eigen::AngleAxisd(
                                               2 * M_PI * h / o_.loop_yaw_hypotheses, Eigen::Vector3d::UnitZ())),
                                           Eigen::Vector3d::Zero()));
      try_guesses(turned);
    }
    guess = ok ? guess : guesses[0];
    PoseGraphEdge e;
    e.from = a.id;
    e.to = b.id;
    e.T_from_to = ok ? r.T_target_source : guess;
    e.information = ok ? EdgeInformation(r, e.T_from_to) : odo_info;
    if (!ok) ++sequential_fallbacks_;
    graph_.edges.push_back(e);
    // Odometry edge beside the registration one: constrains what scans leave
    // free (along corridors), sigma proportional to the distance driven.
    if (ok && odometry_ && o_.odometry_sigma > 0) {
      PoseGraphEdge odo = e;
      odo.T_from_to = guess;
      const double d = std::max(odometry_->Distance(a.timestamp, b.timestamp), 0.05);
      // Turning in place: wheel-radius and axle errors scale the turned angle (5 % here).
      const double turned = Eigen::AngleAxisd(guess.q).angle();
      odo.information = DiagonalInformation(o_.odometry_sigma * d,
                                            o_.odometry_sigma_rotation * M_PI / 180 * d + 0.05 * turned);
      graph_.edges.push_back(odo);
    }
    // Chain the initial estimate along the registered edges.
    graph_.nodes[b.id] = graph_.nodes[a.id] * e.T_from_to;
    if (!odometry_) b.travelled = a.travelled + e.T_from_to.t.norm();
    ctx_.Progress(i, keyframes_.size(), "sequential edges");
  }
}

bool Slam::TryLoop(const Keyframe& a, const Keyframe& b) {
  const Pose guess = graph_.nodes[a.id].Inverse() * graph_.nodes[b.id];
  // Coarse: downsampled clouds, from the current estimate; across sequences
  // (whose relative heading is unknown until a first loop joins them) from
  // several headings, keeping the best-overlapping result.
  const bool join = a.sequence != b.sequence && !joined_.count({a.sequence, b.sequence});
  const int hypotheses = join ? o_.loop_yaw_hypotheses : 1;
  RegistrationResult rough;
  for (int h = 0; h < hypotheses; ++h) {
    const Pose yaw(Eigen::Quaterniond(Eigen::AngleAxisd(2 * M_PI * h / hypotheses, Eigen::Vector3d::UnitZ())),
                   Eigen::Vector3d::Zero());
    const RegistrationResult r = backend_.Align(b.rough, a.rough, guess * yaw, ctx_.threads());
    ctx_.Debug("pose_graph: loop " + std::to_string(a.id) + "-" + std::to_string(b.id) + " rough: converged " +
               std::to_string(r.converged) + " overlap " + std::to_string(r.inlier_fraction) + " error " +
               std::to_string(r.final_error) + " iterations " + std::to_string(r.iterations));
    if (!r.converged || r.final_error > o_.loop_rough_error) continue;
    if (!rough.converged || r.inlier_fraction > rough.inlier_fraction) rough = r;
  }
  auto reject = [&](const std::string& why) {
    ctx_.Debug("pose_graph: loop " + std::to_string(a.id) + "-" + std::to_string(b.id) + " rejected: " + why);
    return false;
  };
  if (!rough.converged || rough.inlier_fraction < o_.loop_rough_overlap)
    return reject("rough overlap " + std::to_string(rough.inlier_fraction) + " error " + std::to_string(rough.final_error));
  if ((rough.T_target_source.t - guess.t).norm() > o_.loop_radius) return reject("rough result far from the guess");
  // Fine: full clouds from the rough result.
  const RegistrationResult fine = backend_.Align(b.cloud, a.cloud, rough.T_target_source, ctx_.threads());
  if (!fine.converged || fine.inlier_fraction < o_.loop_overlap)
    return reject("fine overlap " + std::to_string(fine.inlier_fraction));
  ctx_.Debug("pose_graph: loop " + std::to_string(a.id) + "-" + std::to_string(b.id) + " accepted: overlap " +
             std::to_string(fine.inlier_fraction));
  PoseGraphEdge e;
  e.from = a.id;
  e.to = b.id;
  e.T_from_to = fine.T_target_source;
  e.information = EdgeInformation(fine, e.T_from_to);
  e.loss = o_.loss == "cauchy" ? RobustLoss::kCauchy : o_.loss == "huber" ? RobustLoss::kHuber : RobustLoss::kNone;
  e.loss_scale = o_.loss_scale;
  e.loop = true;
  graph_.edges.push_back(e);
  joined_.insert({a.sequence, b.sequence});
  joined_.insert({b.sequence, a.sequence});
  return true;
}

int Slam::AddLoopEdges() {
  int added = 0;
  for (size_t j = 0; j < keyframes_.size(); j += o_.loop_stride) {
    ctx_.ThrowIfCancelled();
    const Keyframe& b = keyframes_[j];
    const Eigen::Vector3d pb = graph_.nodes[b.id].t;
    // The nearest eligible keyframe of every sequence (own one included).
    std::map<std::string, std::pair<double, int>> nearest;
    for (size_t i = 0; i < j; ++i) {
      const Keyframe& a = keyframes_[i];
      if (a.sequence == b.sequence && b.travelled - a.travelled < o_.loop_min_travel) continue;
      const double d = (graph_.nodes[a.id].t - pb).norm();
      if (d > o_.loop_radius) continue;
      auto& best = nearest.emplace(a.sequence, std::make_pair(1e300, -1)).first->second;
      if (d < best.first) best = {d, a.id};
    }
    for (const auto& [seq, best] : nearest) {
      // Failed candidates are tried again next round, from better estimates.
      if (accepted_.count({best.second, b.id})) continue;
      ++loop_tests_;
      if (TryLoop(keyframes_[best.second], b)) {
        accepted_.insert({best.second, b.id});
        ++added;
      }
    }
    ctx_.Progress(j, keyframes_.size(), "loop closures");
  }
  return added;
}

// T_world_rig at t. Wheel odometry: the latest keyframe at or before t in
// t's odometry segment, moved by odometry (or the first keyframe, backwards).
// Constant velocity: interpolated between the keyframes around t (held at
// the nearest one outside them), within one segment.
Pose Slam::PoseAt(Timestamp t, bool* found) const {
  // Keyframes are in time order (scans sorted by time): binary search, then
  // the neighbour at or before t, else the one after, in t's segment.
  const auto after = std::upper_bound(keyframes_.begin(), keyframes_.end(), t,
                                      [](Timestamp v, const Keyframe& kf) { return v < kf.timestamp; });
  const double td = static_cast<double>(t);
  const Keyframe* before = after != keyframes_.begin() ? &*(after - 1) : nullptr;
  const Keyframe* next = after != keyframes_.end() ? &*after : nullptr;
  if (!odometry_) {
    auto near = [&](const Keyframe* k) {
      return k && std::abs(static_cast<double>(t - k->timestamp)) * o_.seconds_per_unit <= o_.max_scan_gap;
    };
    const bool nb = near(before), nn = near(next);
    *found = nb || nn;
    if (nb && nn && SameSegment(*before, next->timestamp, next->sequence) && next->timestamp > before->timestamp) {
      const double alpha = static_cast<double>(t - before->timestamp) / static_cast<double>(next->timestamp - before->timestamp);
      return Interpolate(graph_.nodes.at(before->id), graph_.nodes.at(next->id), alpha);
    }
    if (nb) return graph_.nodes.at(before->id);
    if (nn) return graph_.nodes.at(next->id);
    return Pose();
  }
  const Keyframe* best = nullptr;
  if (before && odometry_->SameSegment(static_cast<double>(before->timestamp), td))
    best = before;
  else if (next && odometry_->SameSegment(static_cast<double>(next->timestamp), td))
    best = next;
  *found = best != nullptr;
  if (!best) return Pose();
  return graph_.nodes.at(best->id) * odometry_->Relative(static_cast<double>(best->timestamp), td);
}

void Slam::Run() {
  const auto start = std::chrono::steady_clock::now();
  const fs::path scans_root = ctx_.Input("scans");
  kapture::Kapture k(scans_root);
  std::vector<kapture::DataRecord> scans = k.ReadDataRecords(kapture::kSensorLidar);
  std::stable_sort(scans.begin(), scans.end(), [](const auto& a, const auto& b) {
    return a.timestamp < b.timestamp;
  });
  SelectKeyframes(scans, scans_root);
  ctx_.Info("pose_graph: " + std::to_string(keyframes_.size()) + " keyframes of " + std::to_string(scans.size()) + " scans");
  AddSequentialEdges();
  const PoseGraph before = graph_;
  PoseGraphSummary summary;
  PoseGraphOptions solver;
  solver.threads = ctx_.threads();
  for (int round = 0; round < o_.rounds; ++round) {
    const int added = AddLoopEdges();
    ctx_.Info("pose_graph: round " + std::to_string(round + 1) + ": " + std::to_string(added) + " loop edges");
    const PoseGraphSummary s = Optimize(solver, &graph_);
    if (round == 0) summary.initial_cost = s.initial_cost;
    summary.final_cost = s.final_cost;
    summary.iterations += s.iterations;
    summary.report = s.report;
    if (added == 0 && round > 0) break;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  WriteOutputs(scans, before, summary, seconds);
}

void Slam::WriteOutputs(const std::vector<kapture::DataRecord>& scans, const PoseGraph& before,
                        const PoseGraphSummary& summary, double seconds) {
  const fs::path out = ctx_.output_dir();
  // Sensors, rigs and camera records: the recording, else the scans' own.
  kapture::Kapture dataset(o_.dataset.empty() ? ctx_.Input("scans") : fs::path(o_.dataset));
  kapture::Trajectories trajectories;
  for (const auto& r : scans) {
    bool found = false;
    const Pose T_world_rig = PoseAt(r.timestamp, &found);
    if (found) trajectories.Set(r.timestamp, "rig", T_world_rig.Inverse());
  }
  // Cameras at every image: trajectory interpolation (odometry between
  // keyframes) x rig extrinsics (T_camera_world = T_camera_rig T_rig_world).
  int64_t camera_poses = 0;
  if (dataset.HasRecords(kapture::kSensorCamera)) {
    dataset.ForEachDataRecord(kapture::kSensorCamera, [&](const kapture::DataRecord& r) {
      const kapture::Rig* rig = dataset.rigs().RigOf(r.device_id);
      const kapture::RigSensor* rs = rig ? rig->Find(r.device_id) : nullptr;
      if (!rs) return;
      bool found = false;
      const Pose T_world_rig = PoseAt(r.timestamp, &found);
      if (!found) return;
      trajectories.Set(r.timestamp, r.device_id, rs->sensor_from_rig * T_world_rig.Inverse());
      ++camera_poses;
    });
  }
  kapture::WriteTrajectories(out / kapture::layout::kTrajectories, trajectories);
  kapture::WriteSensors(out / kapture::layout::kSensors, dataset.sensors());
  if (!dataset.rigs().empty()) kapture::WriteRigs(out / kapture::layout::kRigs, dataset.rigs());

  Cloud map;
  for (const auto& kf : keyframes_) {
    Cloud c = kf.cloud;
    Transform(graph_.nodes.at(kf.id), &c);
    map.points.insert(map.points.end(), c.points.begin(), c.points.end());
  }
  map = VoxelDownsample(map, o_.map_voxel);
  WritePcd(out / "map.pcd", map);
  WritePly(out / "map.ply", map);
  WriteG2o(out / "pose_graph.g2o", graph_);

  std::vector<PlotSequence> plot_before, plot_after;
  std::vector<std::pair<int, int>> loops;
  for (const auto& e : graph_.edges)
    if (e.loop) loops.emplace_back(e.from, e.to);
  for (const auto& kf : keyframes_) {
    if (plot_after.empty() || plot_after.back().name != kf.sequence) {
      plot_before.push_back({kf.sequence, {}, {}});
      plot_after.push_back({kf.sequence, {}, {}});
    }
    plot_before.back().ids.push_back(kf.id);
    plot_before.back().xy.push_back(before.nodes.at(kf.id).t.head<2>());
    plot_after.back().ids.push_back(kf.id);
    plot_after.back().xy.push_back(graph_.nodes.at(kf.id).t.head<2>());
  }
  WriteTopDown(out / "trajectories", plot_before, plot_after, loops);

  int loop_edges = 0, cross = 0;
  for (const auto& e : graph_.edges) {
    if (!e.loop) continue;
    ++loop_edges;
    if (keyframes_[e.from].sequence != keyframes_[e.to].sequence) ++cross;
  }
  std::set<std::string> sequences;
  for (const auto& kf : keyframes_) sequences.insert(kf.sequence);
  const PlaneResidualStats crisp = MapPlaneResidual(map, o_.map_residual_k, o_.map_residual_radius);
  std::ostringstream loops_json;
  loops_json.precision(16);
  for (const auto& e : graph_.edges) {
    if (!e.loop) continue;
    const Keyframe& a = keyframes_[e.from];
    const Keyframe& b = keyframes_[e.to];
    const Eigen::Vector3d pa = graph_.nodes.at(a.id).t, pb = graph_.nodes.at(b.id).t;
    loops_json << (loops_json.tellp() > 0 ? ",\n    " : "\n    ") << "{\"from\": " << a.id << ", \"to\": " << b.id
               << ", \"from_time\": " << a.timestamp << ", \"to_time\": " << b.timestamp << ", \"from_xy\": ["
               << pa.x() << ", " << pa.y() << "], \"to_xy\": [" << pb.x() << ", " << pb.y() << "]}";
  }
  std::ostringstream j;
  j.precision(10);
  j << "{\n  \"scans\": " << scans.size() << ",\n  \"keyframes\": " << keyframes_.size()
    << ",\n  \"sequences\": " << sequences.size() << ",\n  \"sequential_edges\": "
    << graph_.edges.size() - loop_edges << ",\n  \"sequential_odometry_fallbacks\": " << sequential_fallbacks_
    << ",\n  \"loop_edges\": " << loop_edges << ",\n  \"cross_sequence_loop_edges\": " << cross
    << ",\n  \"loop_candidates_tested\": " << loop_tests_ << ",\n  \"initial_cost\": " << summary.initial_cost
    << ",\n  \"final_cost\": " << summary.final_cost << ",\n  \"camera_poses\": " << camera_poses
    << ",\n  \"information_fallbacks\": " << information_fallbacks_ << ",\n  \"map_points\": " << map.size()
    << ",\n  \"map_plane_residual\": {\"k\": " << o_.map_residual_k << ", \"radius\": " << o_.map_residual_radius
    << ", \"points\": " << crisp.points << ", \"skipped\": " << crisp.skipped << ", \"mean\": " << crisp.mean
    << ", \"median\": " << crisp.median << ", \"rmse\": " << crisp.rmse << ", \"p90\": " << crisp.p90 << "}"
    << ",\n  \"loops\": [" << loops_json.str() << "\n  ]"
    << ",\n  \"seconds\": " << seconds
    << ",\n  \"scans_per_second\": " << scans.size() / std::max(seconds, 1e-9) << "\n}\n";
  WriteFileAtomic(out / "slam.json", j.str());
  ctx_.Info("pose_graph: " + std::to_string(loop_edges) + " loop edges (" + std::to_string(cross) +
            " across sequences), " + summary.report);
}

}  // namespace

void PoseGraphSlam::Run(RunContext& ctx) {
  Slam slam(options(), ctx);
  slam.Run();
}

}  // namespace locforge::lidar

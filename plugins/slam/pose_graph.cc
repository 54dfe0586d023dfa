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
#include "join_consensus.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"
#include "locforge/registration.h"
#include "plot.h"
#include "pose_graph.h"
#include "lidar_stages.h"

namespace locforge::lidar {

namespace {

// A turn by `yaw` (rad) about the platform's up axis, then the translation `t`.
Pose YawPose(double yaw, const Eigen::Vector3d& t = Eigen::Vector3d::Zero()) {
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())), t);
}

// One initial_poses entry, "sequence x y yaw_deg": false when malformed.
bool ParseInitialPose(const std::string& entry, std::string* sequence, Pose* start) {
  std::istringstream s(entry);
  double x, y, yaw;
  if (!(s >> *sequence >> x >> y >> yaw)) return false;
  *start = YawPose(yaw * M_PI / 180, Eigen::Vector3d(x, y, 0));
  return true;
}

}  // namespace

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
  s.Add("refine_correspondence_distance", &O::refine_correspondence_distance,
        "Final pass of accepted sequential and precise loop registrations with the back-end's "
        "max_correspondence_distance set to this (m; 0: none)").Range(0, 100);
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
  s.Add("join_seeds", &O::join_seeds,
        "Joining sequences: seed keyframes nearest the sequence's start (all headings tried)").Range(1, 1000);
  s.Add("join_seed_radius", &O::join_seed_radius, "Seed keyframes lie within this distance of the sequence's start (m)")
      .Min(0);
  s.Add("join_rough_error", &O::join_rough_error,
        "Largest mean residual of the seeds' rough check (m; wrong seed loops are left to the consensus)").Min(0);
  s.Add("join_hypotheses", &O::join_hypotheses, "Frame hypotheses verified per join attempt").Range(1, 100);
  s.Add("join_verify", &O::join_verify, "Loops predicted by a hypothesis and tested to verify it").Range(0, 1000);
  s.Add("join_min_support", &O::join_min_support,
        "Distinct keyframes of a sequence whose loops must agree on its frame to join it").Range(1, 1000);
  s.Add("join_min_verified", &O::join_min_verified,
        "... of them with loops found where the frame hypothesis predicted them (not seeds)").Range(0, 1000);
  s.Add("join_min_verified_fraction", &O::join_min_verified_fraction,
        "Fraction of the loops predicted by the winning hypothesis that must be found").Range(0, 1);
  s.Add("join_max_translation", &O::join_max_translation,
        "Two frame hypotheses agree within this distance at their keyframes (m)").Min(1e-6);
  s.Add("join_max_rotation", &O::join_max_rotation, "... and this rotation (deg)").Range(1e-6, 180);
  s.Add("join_max_rival_ratio", &O::join_max_rival_ratio,
        "Largest verified support of a disagreeing cluster, as a fraction of the winner's (else no join)").Range(0, 1);
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
        "Manual initial-pose corrections, one 'sequence x y yaw_deg' per entry (start pose in the first "
        "sequence's frame; such a sequence is not joined by loop consensus)");
  s.Add("seconds_per_unit", &O::seconds_per_unit, "Duration of one timestamp unit (s)").Range(1e-12, 1);
  LOCFORGE_LIDAR_WHEEL_PARAMS(O);
}

bool PoseGraphSlamOptions::Check(std::string* why) const {
  for (const auto& p : initial_poses) {
    std::string seq;
    Pose start;
    if (!ParseInitialPose(p, &seq, &start)) {
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
      : o_(o),
        ctx_(ctx),
        backend_(MakeBackend(o, ctx, 0)),
        refine_backend_(MakeBackend(o, ctx, o.refine_correspondence_distance)) {
    if (o.motion_prior == "wheel" && o.dataset.empty())
      throw ParamError("slam/pose_graph: dataset is required with motion_prior wheel (the wheel records)");
    if (o.motion_prior == "wheel")
      odometry_ = std::make_unique<WheelOdometry>(WheelOdometry::FromKapture(o.dataset, o.Wheels()));
  }

  void Run();

 private:
  // The back-end with registration_params and, when max_correspondence > 0,
  // max_correspondence_distance overridden (the key every registration
  // back-end declares, plugins/registration/README.md).
  static RegistrationBackend MakeBackend(const PoseGraphSlamOptions& o, RunContext& ctx, double max_correspondence) {
    std::vector<std::pair<std::string, std::string>> params;
    for (const auto& kv : o.registration_params) {
      const size_t eq = kv.find('=');
      if (max_correspondence > 0 && kv.substr(0, eq) == "max_correspondence_distance") continue;
      params.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
    }
    if (max_correspondence > 0) {
      std::ostringstream v;
      v.precision(17);
      v << max_correspondence;
      params.emplace_back("max_correspondence_distance", v.str());
    }
    return RegistrationBackend::Create(ctx, o.registration, params);
  }
  // The final pass of refine_correspondence_distance from an accepted
  // registration `first` of source -> target: its pose and information when
  // it converged within that distance of `first`, else `first` unchanged.
  // `first`'s overlap is kept (acceptance is decided on the first pass).
  RegistrationResult Refine(const RegistrationResult& first, const Cloud& source, const Cloud& target);
  void SelectKeyframes(const std::vector<kapture::DataRecord>& scans, const fs::path& scans_root);
  void AddSequentialEdges();
  int AddLoopEdges();
  bool TryLoop(const Keyframe& a, const Keyframe& b);
  // Coarse-to-fine check of a loop b -> a: the rough registration from each
  // guess of T_ab, then the precise one from each distinct rough solution:
  // the accepted precise results (at most one with one guess).
  std::vector<RegistrationResult> CheckLoop(const Keyframe& a, const Keyframe& b, const std::vector<Pose>& guesses,
                                            double rough_error);
  void AddLoopEdge(const Keyframe& a, const Keyframe& b, const RegistrationResult& fine);
  // Joins components (sequences sharing a frame) when loops agree on their
  // relative frame (join_consensus.h), until all are in the first
  // keyframe's or no more join; returns the number of joins.
  int JoinComponents();
  bool TryJoin(int A, int B);
  // Same sequence and motion segment (odometry segment, or no gap above max_scan_gap).
  bool SameSegment(const Keyframe& a, Timestamp t, const std::string& sequence) const;
  Pose MotionGuess(size_t i) const;
  Matrix6d EdgeInformation(const RegistrationResult& r, const Pose& T_ab);  // counts fallbacks
  Pose PoseAt(Timestamp t, bool* found) const;
  void WriteOutputs(const std::vector<kapture::DataRecord>& scans, const PoseGraph& before,
                    const PoseGraphSummary& summary, double seconds);

  const PoseGraphSlamOptions& o_;
  RunContext& ctx_;
  std::unique_ptr<WheelOdometry> odometry_;  // null with motion_prior constant_velocity
  RegistrationBackend backend_;
  RegistrationBackend refine_backend_;  // backend_ with the refine gate (unused when it is 0)
  int refinements_ = 0, refinements_rejected_ = 0;
  std::vector<Keyframe> keyframes_;  // sequences in time order, each in time order
  PoseGraph graph_;
  std::set<std::pair<int, int>> accepted_;  // loop edges added
  int64_t loop_tests_ = 0;
  // Sequences sharing a frame: sequence -> component (id of its first
  // keyframe); all start apart and are merged by JoinComponents.
  std::map<std::string, int> component_;
  PoseGraph before_;  // the graph before optimisation (joined components moved into the world frame)
  int joins_ = 0, join_attempts_ = 0, join_tests_ = 0, join_rejected_loops_ = 0;
  std::map<std::pair<int, int>, std::pair<size_t, size_t>> join_failed_;  // (A, B) -> their sizes then
  int sequential_fallbacks_ = 0;
  int information_fallbacks_ = 0;  // registration information unusable: fixed sigmas used
  std::map<std::string, Pose> start_poses_;
};

void Slam::SelectKeyframes(const std::vector<kapture::DataRecord>& scans, const fs::path& scans_root) {
  const double max_angle = o_.keyframe_angle * M_PI / 180;
  std::map<std::string, Pose> corrections;
  for (const auto& p : o_.initial_poses) {
    std::string seq;
    Pose start;
    if (!ParseInitialPose(p, &seq, &start))  // also refused by PoseGraphSlamOptions::Check
      throw ParamError("initial_poses: '" + p + "' is not 'sequence x y yaw_deg'");
    corrections[seq] = start;
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
    // A manual initial pose puts the sequence in the first one's frame:
    // joined from the start (its loops are searched like any other).
    component_.emplace(kf.sequence, corrections.count(seq) ? 0 : kf.id);
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
Matrix6d Slam::EdgeInformation(const RegistrationResult& r, const Pose& T_ab) {
  const double sigma_r = o_.sigma_rotation * M_PI / 180;
  const Matrix6d fixed = DiagonalInformation(o_.sigma_translation, sigma_r);
  if (o_.edge_information == "fixed") return fixed;
  Matrix6d out;
  if (!NormalizeInformation(RegistrationInformationToEdge(r.information, T_ab), o_.sigma_translation, sigma_r,
                            o_.information_max_ratio, &out)) {
    ++information_fallbacks_;
    return fixed;
  }
  return out;
}

RegistrationResult Slam::Refine(const RegistrationResult& first, const Cloud& source, const Cloud& target) {
  if (o_.refine_correspondence_distance <= 0) return first;
  RegistrationResult fine = refine_backend_.Align(source, target, first.T_target_source, ctx_.threads());
  const double moved = (fine.T_target_source.t - first.T_target_source.t).norm();
  if (!fine.converged || moved > o_.refine_correspondence_distance) {
    ++refinements_rejected_;
    return first;
  }
  ++refinements_;
  fine.inlier_fraction = first.inlier_fraction;
  return fine;
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
        turned.push_back(guesses[0] * YawPose(2 * M_PI * h / o_.loop_yaw_hypotheses));
      try_guesses(turned);
    }
    guess = ok ? guess : guesses[0];
    if (ok) r = Refine(r, b.cloud, a.cloud);
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

std::vector<RegistrationResult> Slam::CheckLoop(const Keyframe& a, const Keyframe& b,
                                                const std::vector<Pose>& guesses, double rough_error) {
  const std::string name = "pose_graph: loop " + std::to_string(a.id) + "-" + std::to_string(b.id);
  // Coarse: downsampled clouds, from each guess; the distinct solutions
  // passing the thresholds are kept (the best overlap of each).
  std::vector<RegistrationResult> roughs;
  for (const Pose& guess : guesses) {
    const RegistrationResult r = backend_.Align(b.rough, a.rough, guess, ctx_.threads());
    ctx_.Debug(name + " rough: converged " + std::to_string(r.converged) + " overlap " +
               std::to_string(r.inlier_fraction) + " error " + std::to_string(r.final_error) + " iterations " +
               std::to_string(r.iterations));
    if (!r.converged || r.final_error > rough_error || r.inlier_fraction < o_.loop_rough_overlap) continue;
    if ((r.T_target_source.t - guess.t).norm() > o_.loop_radius) {
      ctx_.Debug(name + " rough result far from the guess");
      continue;
    }
    bool same = false;
    for (auto& k : roughs)
      if ((k.T_target_source.t - r.T_target_source.t).norm() < 0.5 &&
          RotationAngleDeg(k.T_target_source.q, r.T_target_source.q) < 10) {
        if (r.inlier_fraction > k.inlier_fraction) k = r;
        same = true;
        break;
      }
    if (!same) roughs.push_back(r);
  }
  if (roughs.empty()) ctx_.Debug(name + " rejected: no rough solution");
  // Fine: full clouds from each rough solution.
  std::vector<RegistrationResult> out;
  for (const auto& rough : roughs) {
    const RegistrationResult fine = backend_.Align(b.cloud, a.cloud, rough.T_target_source, ctx_.threads());
    if (!fine.converged || fine.inlier_fraction < o_.loop_overlap) {
      ctx_.Debug(name + " rejected: fine overlap " + std::to_string(fine.inlier_fraction));
      continue;
    }
    ctx_.Debug(name + " fine: overlap " + std::to_string(fine.inlier_fraction));
    out.push_back(Refine(fine, b.cloud, a.cloud));
  }
  return out;
}

void Slam::AddLoopEdge(const Keyframe& a, const Keyframe& b, const RegistrationResult& fine) {
  PoseGraphEdge e;
  e.from = a.id;
  e.to = b.id;
  e.T_from_to = fine.T_target_source;
  e.information = EdgeInformation(fine, e.T_from_to);
  e.loss = o_.loss == "cauchy" ? RobustLoss::kCauchy : o_.loss == "huber" ? RobustLoss::kHuber : RobustLoss::kNone;
  e.loss_scale = o_.loss_scale;
  e.loop = true;
  graph_.edges.push_back(e);
  accepted_.insert({std::min(a.id, b.id), std::max(a.id, b.id)});
}

bool Slam::TryLoop(const Keyframe& a, const Keyframe& b) {
  const Pose guess = graph_.nodes[a.id].Inverse() * graph_.nodes[b.id];
  const std::vector<RegistrationResult> fine = CheckLoop(a, b, {guess}, o_.loop_rough_error);
  if (fine.empty()) return false;
  AddLoopEdge(a, b, fine.front());
  return true;
}

int Slam::JoinComponents() {
  int joined = 0;
  const int anchor = component_.at(keyframes_.front().sequence);
  for (bool progress = true; progress;) {
    progress = false;
    std::set<int> components;  // by first keyframe: in time order
    std::map<int, size_t> sizes;
    for (const auto& kf : keyframes_) ++sizes[component_.at(kf.sequence)];
    for (const auto& [seq, c] : component_) components.insert(c);
    // Each component B to the anchor's, else to an earlier component (two
    // sequences that overlap each other more than the rest join first, then
    // together); a pair that failed is tried again only once either grew.
    for (const int B : components) {
      if (B == anchor) continue;
      std::vector<int> targets = {anchor};
      for (const int A : components)
        if (A != anchor && A < B) targets.push_back(A);
      for (const int A : targets) {
        const std::pair<size_t, size_t> state(sizes[A], sizes[B]);
        const auto failed = join_failed_.find({A, B});
        if (failed != join_failed_.end() && failed->second == state) continue;
        if (TryJoin(A, B)) {
          ++joined;
          progress = true;
          break;
        }
        join_failed_[{A, B}] = state;
      }
      if (progress) break;  // components changed: enumerate again
    }
  }
  return joined;
}

// Joins component B to A (header of join_consensus.h): seed loops between
// B's keyframes nearest their sequence's start and A's nearest keyframes
// (the frames agree only near the common start; all headings tried), then
// the hypotheses of T_A_B, best-supported first, each verified by the loops
// it predicts along B; B moves into A's frame with the loops that agree.
bool Slam::TryJoin(int A, int B) {
  ++join_attempts_;
  std::vector<const Keyframe*> ka, kb;
  for (const auto& kf : keyframes_) {
    const int c = component_.at(kf.sequence);
    if (c == A) ka.push_back(&kf);
    if (c == B) kb.push_back(&kf);
  }
  std::string name_a, name_b;
  for (const auto& [seq, c] : component_) {
    if (c == A) name_a += (name_a.empty() ? "" : "+") + seq;
    if (c == B) name_b += (name_b.empty() ? "" : "+") + seq;
  }
  auto nearest_a = [&](const Eigen::Vector3d& p) -> const Keyframe* {
    const Keyframe* best = nullptr;
    double best_d = o_.loop_radius;
    for (const Keyframe* a : ka) {
      const double d = (graph_.nodes.at(a->id).t - p).norm();
      if (d <= best_d) best_d = d, best = a;
    }
    return best;
  };
  std::vector<JoinCandidate> candidates;
  std::vector<RegistrationResult> fines;  // parallel to candidates
  std::set<std::pair<int, int>> tested;
  auto test = [&](const Keyframe& a, const Keyframe& b, const std::vector<Pose>& guesses, double rough_error,
                  bool predicted) {
    tested.insert({a.id, b.id});
    ++join_tests_;
    int ok = 0;
    for (const auto& f : CheckLoop(a, b, guesses, rough_error)) {
      JoinCandidate c;
      c.a = a.id;
      c.b = b.id;
      c.T_A_B = graph_.nodes.at(a.id) * f.T_target_source * graph_.nodes.at(b.id).Inverse();
      c.p_b = graph_.nodes.at(b.id).t;
      c.overlap = f.inlier_fraction;
      c.predicted = predicted;
      candidates.push_back(c);
      fines.push_back(f);
      ++ok;
    }
    return ok;
  };
  // Seeds: sequences start near the same place, at an unknown heading. B's
  // keyframes within join_seed_radius of its start p0 (its first keyframe; B's
  // frame = A's up to a turn about p0), every loop_stride-th, nearest first;
  // for each of loop_yaw_hypotheses turns H about p0, against the keyframe
  // of A nearest H p_b, from the guess T_ab = T_A_a^-1 H T_B_b.
  const Eigen::Vector3d p0 = graph_.nodes.at(kb.front()->id).t;
  std::vector<const Keyframe*> near_start;
  for (const Keyframe* b : kb)
    if ((graph_.nodes.at(b->id).t - p0).norm() <= o_.join_seed_radius) near_start.push_back(b);
  std::stable_sort(near_start.begin(), near_start.end(), [&](const Keyframe* x, const Keyframe* y) {
    return (graph_.nodes.at(x->id).t - p0).norm() < (graph_.nodes.at(y->id).t - p0).norm();
  });
  int seeds = 0;
  for (size_t i = 0; i < near_start.size() && seeds < o_.join_seeds; i += o_.loop_stride, ++seeds) {
    const Keyframe& b = *near_start[i];
    std::map<int, std::vector<Pose>> guesses;  // a -> guesses
    for (int h = 0; h < o_.loop_yaw_hypotheses; ++h) {
      const Pose turn = YawPose(2 * M_PI * h / o_.loop_yaw_hypotheses);
      const Pose H = Pose(Eigen::Quaterniond::Identity(), p0) * turn * Pose(Eigen::Quaterniond::Identity(), -p0);
      const Keyframe* a = nearest_a(H * graph_.nodes.at(b.id).t);
      if (a) guesses[a->id].push_back(graph_.nodes.at(a->id).Inverse() * H * graph_.nodes.at(b.id));
    }
    for (const auto& [a, g] : guesses) test(keyframes_[a], b, g, o_.join_rough_error, false);
  }
  JoinConsensusOptions co;
  co.max_translation = o_.join_max_translation;
  co.max_rotation_deg = o_.join_max_rotation;
  co.min_support = o_.join_min_support;
  co.min_verified = o_.join_min_verified;
  co.max_rival_ratio = o_.join_max_rival_ratio;
  JoinConsensus r = FindJoinConsensus(candidates, co);
  std::ostringstream log;
  log << "pose_graph: join " << name_b << " to " << name_a << ": " << seeds << " seeds, " << candidates.size() << " seed loops";
  // Verification of the hypotheses, best-supported first (one per cluster):
  // the loops each predicts along B are tested from its guess.
  std::vector<std::pair<int, size_t>> verified;  // hypothesis (candidate), predicted loops tested
  // Joined when the consensus is found and its hypotheses' predicted loops
  // were found often enough (a wrong heading predicts loops that are not there).
  auto accept = [&] {
    if (!r.found) return false;
    size_t tested_pred = 0, found_pred = 0;
    for (const auto& [v, n] : verified)
      if (HypothesesAgree(candidates[v], candidates[r.centre], co)) tested_pred += n;
    std::set<std::pair<int, int>> pairs;
    for (int i : r.inliers)
      if (candidates[i].predicted) pairs.insert({candidates[i].a, candidates[i].b});
    found_pred = pairs.size();
    return found_pred >= o_.join_min_verified_fraction * tested_pred;
  };
  for (int h = 0; h < o_.join_hypotheses && !accept() && o_.join_verify > 0; ++h) {
    int next = -1;
    for (int i = 0; i < static_cast<int>(candidates.size()); ++i) {
      bool seen = false;
      for (const auto& v : verified) seen = seen || HypothesesAgree(candidates[v.first], candidates[i], co);
      if (seen || candidates[i].predicted) continue;
      if (next < 0 || r.supports[i] > r.supports[next] ||
          (r.supports[i] == r.supports[next] && candidates[i].overlap > candidates[next].overlap))
        next = i;
    }
    if (next < 0) break;
    const Pose H = candidates[next].T_A_B;
    std::vector<std::pair<const Keyframe*, const Keyframe*>> predicted;
    for (size_t i = 0; i < kb.size(); ++i) {  // every keyframe (the seeds took every loop_stride-th)
      const Keyframe* a = nearest_a(H * graph_.nodes.at(kb[i]->id).t);
      if (a && !tested.count({a->id, kb[i]->id})) predicted.emplace_back(a, kb[i]);
    }
    // At most join_verify of them, spread along B.
    const size_t n = std::min<size_t>(predicted.size(), o_.join_verify);
    verified.emplace_back(next, n);
    int ok = 0;
    for (size_t k = 0; k < n; ++k) {
      const auto [a, b] = predicted[k * predicted.size() / n];
      ok += test(*a, *b, {graph_.nodes.at(a->id).Inverse() * H * graph_.nodes.at(b->id)}, o_.loop_rough_error,
                 true) > 0;
    }
    log << "; hypothesis " << h + 1 << " (support " << r.supports[next] << "): " << ok << " of " << n
        << " predicted loops found";
    r = FindJoinConsensus(candidates, co);
  }
  log << "; consensus: support " << r.support << " (verified " << r.verified << ", rival " << r.rival_verified
      << "), " << r.inliers.size() << " of " << candidates.size() << " loops agree";
  if (!accept()) {
    ctx_.Info(log.str() + ": not joined");
    return false;
  }
  // B into A's frame (and its pre-optimisation copy, for the plot).
  for (const Keyframe* b : kb) {
    graph_.nodes[b->id] = r.T_A_B * graph_.nodes.at(b->id);
    before_.nodes[b->id] = r.T_A_B * before_.nodes.at(b->id);
  }
  for (int i : r.inliers) {
    const Keyframe& a = keyframes_[candidates[i].a];
    const Keyframe& b = keyframes_[candidates[i].b];
    if (!accepted_.count({std::min(a.id, b.id), std::max(a.id, b.id)})) AddLoopEdge(a, b, fines[i]);
  }
  join_rejected_loops_ += static_cast<int>(r.outliers.size());
  for (auto& [seq, c] : component_)
    if (c == B) c = A;
  ++joins_;
  ctx_.Info(log.str() + ": joined");
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
      // Sequences not joined yet: only through JoinComponents.
      if (component_.at(a.sequence) != component_.at(b.sequence)) continue;
      const double d = (graph_.nodes[a.id].t - pb).norm();
      if (d > o_.loop_radius) continue;
      auto& best = nearest.emplace(a.sequence, std::make_pair(1e300, -1)).first->second;
      if (d < best.first) best = {d, a.id};
    }
    for (const auto& [seq, best] : nearest) {
      // Failed candidates are tried again next round, from better estimates.
      if (accepted_.count({best.second, b.id})) continue;
      ++loop_tests_;
      if (TryLoop(keyframes_[best.second], b)) ++added;
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
  before_ = graph_;
  PoseGraphSummary summary;
  PoseGraphOptions solver;
  solver.threads = ctx_.threads();
  for (int round = 0; round < o_.rounds; ++round) {
    const size_t edges = graph_.edges.size();
    const int joined = JoinComponents();
    AddLoopEdges();
    const int added = static_cast<int>(graph_.edges.size() - edges);  // join loops + the others
    ctx_.Info("pose_graph: round " + std::to_string(round + 1) + ": " + std::to_string(joined) +
              " sequences joined, " + std::to_string(added) + " loop edges");
    const PoseGraphSummary s = Optimize(solver, &graph_);
    if (round == 0) summary.initial_cost = s.initial_cost;
    summary.final_cost = s.final_cost;
    summary.iterations += s.iterations;
    summary.report = s.report;
    if (added == 0 && round > 0) break;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  WriteOutputs(scans, before_, summary, seconds);
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
    << ",\n  \"loop_candidates_tested\": " << loop_tests_ << ",\n  \"joins\": " << joins_
    << ",\n  \"join_attempts\": " << join_attempts_ << ",\n  \"join_candidates_tested\": " << join_tests_
    << ",\n  \"join_rejected_loops\": " << join_rejected_loops_ << ",\n  \"initial_cost\": " << summary.initial_cost
    << ",\n  \"final_cost\": " << summary.final_cost << ",\n  \"camera_poses\": " << camera_poses
    << ",\n  \"information_fallbacks\": " << information_fallbacks_ << ",\n  \"refinements\": " << refinements_
    << ",\n  \"refinements_rejected\": " << refinements_rejected_ << ",\n  \"map_points\": " << map.size()
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

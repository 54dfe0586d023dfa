#include "slam.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <chrono>
#include <cmath>
#include <sstream>
#include <tuple>

namespace locforge::lidar {

namespace {

Matrix6d DiagonalInformation(double sigma_t, double sigma_r_rad) {
  Vector6d d;
  d << Eigen::Vector3d::Constant(1 / (sigma_t * sigma_t)), Eigen::Vector3d::Constant(1 / (sigma_r_rad * sigma_r_rad));
  return d.asDiagonal();
}

}  // namespace

bool ParseInitialPose(const std::string& entry, std::string* sequence, Pose* start) {
  std::istringstream s(entry);
  double x, y, yaw;
  if (!(s >> *sequence >> x >> y >> yaw)) return false;
  *start = YawPose(yaw * M_PI / 180, Eigen::Vector3d(x, y, 0));
  return true;
}

bool SlamOptions::Check(std::string* why) const {
  for (const auto& p : initial_poses) {
    std::string seq;
    Pose start;
    if (!ParseInitialPose(p, &seq, &start)) {
      if (why) *why = "initial_poses: '" + p + "' is not 'sequence x_m y_m yaw_deg'";
      return false;
    }
  }
  for (const auto& entry : coarse_params) {
    const size_t eq = entry.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == entry.size()) {
      if (why) *why = "coarse_params: '" + entry + "' is not key=value (e.g. rotation_epsilon=0.002)";
      return false;
    }
  }
  if (unjoined != "error" && unjoined != "separate") {
    if (why) *why = "unjoined: '" + unjoined + "' is not error or separate";
    return false;
  }
  return true;
}

Slam::Slam(const SlamOptions& options, const WheelOdometry* odometry, Registrar registrar, Registrar refine,
           int threads, SlamHooks hooks)
    : o_(options),
      odometry_(odometry),
      motion_(odometry, options.max_scan_gap_s, options.seconds_per_unit),
      registrar_(std::move(registrar)),
      refine_registrar_(std::move(refine)),
      threads_(threads),
      hooks_(std::move(hooks)) {}

void Slam::SelectKeyframes(const std::vector<ScanStamp>& scans, const std::function<Cloud(size_t)>& read,
                           bool none_is_error) {
  std::map<std::string, Pose> corrections;
  for (const auto& p : o_.initial_poses) {
    std::string seq;
    Pose start;
    if (!ParseInitialPose(p, &seq, &start))  // also refused by SlamOptions::Check
      throw ParamError("initial_poses: '" + p + "' is not 'sequence x y yaw_deg'");
    corrections[seq] = start;
  }
  ScanContextOptions sco;
  std::map<std::string, Pose> start_poses;
  for (const KeyframeChoice& c : ChooseKeyframes(scans, motion_, o_.keyframe_distance_m, o_.keyframe_angle_rad)) {
    const ScanStamp& s = scans[c.scan];
    Keyframe kf;
    kf.id = static_cast<int>(keyframes_.size());
    kf.timestamp = s.timestamp;
    kf.sequence = s.sequence;
    kf.travelled = c.travelled;
    kf.cloud = read(c.scan);
    kf.rough = VoxelDownsample(kf.cloud, o_.loop_rough_voxel_m);
    kf.context = MakeScanContext(kf.cloud, sco);
    // Initial pose: the sequence's start (identity, or the manual correction)
    // x odometry (constant velocity: chained by the sequential registrations).
    if (c.segment_start) {
      const auto m = corrections.find(s.sequence);
      if (!start_poses.count(s.sequence)) start_poses[s.sequence] = m != corrections.end() ? m->second : Pose();
      graph_.nodes[kf.id] = start_poses[s.sequence];
    } else {
      const Keyframe& last = keyframes_.back();
      graph_.nodes[kf.id] = graph_.nodes[last.id] * motion_.Relative(last.timestamp, kf.timestamp);
    }
    // A manual initial pose puts the sequence in the first one's frame: part
    // 0, the part of keyframe 0.
    const bool manual = corrections.count(s.sequence) > 0;
    if (manual) manual_.insert(s.sequence);
    component_.emplace(kf.sequence, manual ? 0 : kf.id);
    keyframes_.push_back(std::move(kf));
  }
  if (keyframes_.empty() && none_is_error)
    throw InputError("records_lidar.txt", 0, "records_lidar",
                     odometry_ ? "no scan covered by odometry" : "no scan");
  if (o_.planar) {
    graph_.planar_sigma_z = o_.planar_sigma_z_m;
    graph_.planar_sigma_tilt = o_.planar_sigma_tilt_rad;
  }
}

int Slam::AnchorComponent() const { return component_.at(keyframes_.front().sequence); }

// Guess of T_{i-1,i}: wheel odometry, or constant velocity: the previous
// keyframe step's twist xi = Log(T_{i-2,i-1}) scaled by the ratio of the time
// steps (identity at a segment's start).
Pose Slam::MotionGuess(size_t i) const {
  const Keyframe& a = keyframes_[i - 1];
  const Keyframe& b = keyframes_[i];
  if (odometry_) return motion_.Relative(a.timestamp, b.timestamp);
  if (i < 2 || !motion_.SameSegment(keyframes_[i - 2].sequence, keyframes_[i - 2].timestamp, a.sequence, a.timestamp))
    return Pose();
  const Keyframe& z = keyframes_[i - 2];
  const Pose previous = graph_.nodes.at(z.id).Inverse() * graph_.nodes.at(a.id);
  const double ratio = static_cast<double>(b.timestamp - a.timestamp) / std::max<double>(1, a.timestamp - z.timestamp);
  return ExpSE3(LogSE3(previous) * ratio);
}

// The back-end's Hessian in the edge's coordinates, rescaled so its best
// directions have the sigmas (SlamOptions); fixed sigmas when asked
// for or when the Hessian is unusable.
Matrix6d Slam::EdgeInformation(const RegistrationResult& r, const Pose& T_ab) {
  const double sigma_r = o_.sigma_rotation_rad;
  const Matrix6d fixed = DiagonalInformation(o_.sigma_translation_m, sigma_r);
  if (o_.edge_information == "fixed") return fixed;
  Matrix6d out;
  if (!NormalizeInformation(RegistrationInformationToEdge(r.information, T_ab), o_.sigma_translation_m, sigma_r,
                            o_.information_max_ratio, &out)) {
    ++stats_.information_fallbacks;
    return fixed;
  }
  return out;
}

// The final pass of an accepted registration (refine_correspondence_distance):
// its pose and information when it converged near `first`, else `first`;
// `first`'s overlap is kept (acceptance is decided on the first pass).
RegistrationResult Slam::Refine(const RegistrationResult& first, const Cloud& source, const Cloud& target) {
  return Refine(first, source, target, refine_registrar_);
}

RegistrationResult Slam::Refine(const RegistrationResult& first, const Cloud& source, const Cloud& target,
                                const Registrar& refine) {
  if (o_.refine_correspondence_distance_m <= 0) return first;
  RegistrationResult fine = refine(source, target, first.T_target_source);
  const double moved = (fine.T_target_source.t - first.T_target_source.t).norm();
  if (!fine.converged || moved > o_.refine_correspondence_distance_m) {
    std::lock_guard<std::mutex> lock(stats_mutex_);  // workers refine side by side
    ++stats_.refinements_rejected;
    return first;
  }
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.refinements;
  }
  fine.inlier_fraction = first.inlier_fraction;
  return fine;
}

LoopCheckOptions Slam::LoopOptions(double rough_error) const {
  LoopCheckOptions lo;
  lo.rough_overlap = o_.loop_rough_overlap;
  lo.rough_error_m = rough_error;
  lo.max_guess_distance_m = o_.loop_radius_m;
  lo.overlap = o_.loop_overlap;
  return lo;
}

Refiner Slam::MakeRefiner() {
  return [this](const RegistrationResult& r, const Cloud& s, const Cloud& t) { return Refine(r, s, t); };
}

std::vector<RegistrationResult> Slam::CheckLoop(const Keyframe& a, const Keyframe& b, const std::vector<Pose>& guesses,
                                                double rough_error) {
  return lidar::CheckLoop(registrar_, MakeRefiner(), [this](const Keyframe& k) { return CloudOf(k); }, a, b, guesses,
                          LoopOptions(rough_error));
}

bool Slam::RegisterSequential(size_t i, Pose* guess, RegistrationResult* r) {
  return RegisterSequential(i, guess, r, registrar_, refine_registrar_);
}

bool Slam::RegisterSequential(size_t i, Pose* guess, RegistrationResult* r, const Registrar& registrar,
                              const Registrar& refine) {
  const Keyframe& a = keyframes_[i - 1];
  const Keyframe& b = keyframes_[i];
  // Constant velocity mispredicts sudden turns and stops: the zero-motion
  // guess is tried too (the better-overlapping accepted result is kept),
  // then, when both fail, headings around the guess.
  std::vector<Pose> guesses = {MotionGuess(i)};
  if (!odometry_ && (guesses[0].t.norm() > 0.05 || Eigen::AngleAxisd(guesses[0].q).angle() > 0.05))
    guesses.push_back(Pose());
  *guess = guesses[0];
  bool ok = false;
  auto try_guesses = [&](const std::vector<Pose>& candidates) {
    for (const Pose& g : candidates) {
      const RegistrationResult c = registrar(b.cloud, a.cloud, g);
      const bool c_ok = c.converged && c.inlier_fraction >= o_.min_overlap &&
                        (c.T_target_source.t - g.t).norm() < o_.max_guess_deviation_m;
      if (c_ok && (!ok || c.inlier_fraction > r->inlier_fraction)) {
        *r = c;
        *guess = g;
        ok = true;
      }
    }
  };
  try_guesses(guesses);
  if (!ok && !odometry_) {
    std::vector<Pose> turned;
    for (int h = 1; h < o_.loop_yaw_hypotheses; ++h)
      turned.push_back(guesses[0] * YawPose(2 * M_PI * h / o_.loop_yaw_hypotheses));
    try_guesses(turned);
  }
  if (!ok) *guess = guesses[0];
  if (ok) *r = Refine(*r, b.cloud, a.cloud, refine);
  return ok;
}

bool Slam::ForEachOnWorkers(size_t count, const std::function<void(size_t n, size_t worker)>& fn,
                            const std::string& what) {
  if (workers_.size() < 2 || count == 0) return false;
  // Runs of consecutive items per worker: neighbouring items share clouds
  // (keyframe i is in pairs i and i+1), which a worker's back-ends keep.
  constexpr size_t kRun = 8;
  std::atomic<size_t> next{0}, done{0};
  std::atomic<bool> stop{false};
  std::vector<std::exception_ptr> errors(workers_.size());
  auto work = [&](size_t w) {
    try {
      for (size_t first = next.fetch_add(kRun); first < count && !stop; first = next.fetch_add(kRun)) {
        for (size_t n = first; n < std::min(first + kRun, count) && !stop; ++n) {
          fn(n, w);
          ++done;
          if (w == 0) {  // hooks are called from this thread only
            hooks_.check_cancelled();
            if (!what.empty()) hooks_.progress(done, count, what);
          }
        }
      }
    } catch (...) {
      errors[w] = std::current_exception();
      stop = true;
    }
  };
  std::vector<std::thread> threads;
  for (size_t w = 1; w < workers_.size(); ++w) threads.emplace_back(work, w);
  work(0);
  for (auto& t : threads) t.join();
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
  return true;
}

void Slam::RegisterSequentialAll(const std::vector<size_t>& items, std::vector<SequentialResult>* out,
                                 const std::string& what) {
  if (!odometry_) return;  // guesses chain through the previous results otherwise
  ForEachOnWorkers(
      items.size(),
      [&](size_t n, size_t w) {
        SequentialResult& s = (*out)[items[n]];
        s.ok = RegisterSequential(items[n], &s.guess, &s.r, workers_[w].first, workers_[w].second);
        s.done = true;
      },
      what);
}

bool Slam::RegisteredSequential(size_t i, const std::vector<SequentialResult>& side_by_side, Pose* guess,
                                RegistrationResult* r) {
  const SequentialResult& s = side_by_side[i];
  if (!s.done) return RegisterSequential(i, guess, r);
  *guess = s.guess;
  *r = s.r;
  return s.ok;
}

void Slam::AddSequentialEdges() {
  std::map<std::string, std::vector<std::pair<size_t, double>>> odometry_edges;
  std::vector<long> sequential_edge(keyframes_.size(), -1);  // per keyframe i: the edge (i-1, i)
  std::vector<bool> accepted(keyframes_.size(), false);      // ... from an accepted registration
  const Matrix6d odo_info = DiagonalInformation(5 * o_.sigma_translation_m, 5 * o_.sigma_rotation_rad);
  std::vector<size_t> items;
  for (size_t i = 1; i < keyframes_.size(); ++i)
    if (motion_.SameSegment(keyframes_[i - 1].sequence, keyframes_[i - 1].timestamp, keyframes_[i].sequence,
                            keyframes_[i].timestamp))
      items.push_back(i);
  std::vector<SequentialResult> side_by_side(keyframes_.size());
  RegisterSequentialAll(items, &side_by_side, "sequential edges");
  for (size_t i = 1; i < keyframes_.size(); ++i) {
    hooks_.check_cancelled();
    const Keyframe& a = keyframes_[i - 1];
    Keyframe& b = keyframes_[i];
    if (!motion_.SameSegment(a.sequence, a.timestamp, b.sequence, b.timestamp)) continue;
    Pose guess;
    RegistrationResult r;
    const bool ok = RegisteredSequential(i, side_by_side, &guess, &r);
    PoseGraphEdge e;
    e.from = a.id;
    e.to = b.id;
    e.T_from_to = ok ? r.T_target_source : guess;
    e.information = ok ? EdgeInformation(r, e.T_from_to) : odo_info;
    if (!ok) ++stats_.sequential_fallbacks;
    sequential_edge[i] = static_cast<long>(graph_.edges.size());
    accepted[i] = ok;
    graph_.edges.push_back(e);
    // Odometry edge beside the registration one: constrains what scans leave
    // free (along corridors), sigma proportional to the distance driven.
    if (ok && odometry_ && o_.odometry_sigma_m_per_m > 0) {
      PoseGraphEdge odo = e;
      odo.T_from_to = guess;
      const double d = std::max(motion_.Distance(a.timestamp, b.timestamp), 0.05);
      // Turning in place: wheel-radius and axle errors scale the turned angle (5 % here).
      const double turned = Eigen::AngleAxisd(guess.q).angle();
      odo.information = DiagonalInformation(o_.odometry_sigma_m_per_m * d,
                                            o_.odometry_sigma_rotation_rad_per_m * d + 0.05 * turned);
      odometry_edges[b.sequence].emplace_back(graph_.edges.size(), YawOf(e.T_from_to));
      graph_.edges.push_back(odo);
    }
    graph_.nodes[b.id] = graph_.nodes[a.id] * e.T_from_to;  // chain the initial estimate
    if (!odometry_) b.travelled = a.travelled + e.T_from_to.t.norm();
    hooks_.progress(i, keyframes_.size(), "sequential edges");
  }
  if (o_.odometry_yaw_calibration) CalibrateAndRedo(odometry_edges, sequential_edge, accepted);
  for (Keyframe& kf : keyframes_) std::vector<double>().swap(kf.cloud.times);  // no longer needed
}

void Slam::CalibrateAndRedo(const std::map<std::string, std::vector<std::pair<size_t, double>>>& odometry_edges,
                            const std::vector<long>& sequential_edge, const std::vector<bool>& accepted) {
  CalibrateOdometryYaw(odometry_edges);
  // The scans were undistorted with the uncalibrated turns: during a spin
  // each is skewed by (k - 1) x its own turn, and registrations between
  // skewed scans turn too far or too short, the same way at every step.
  const std::vector<bool> changed = RedeskewKeyframes();
  std::vector<size_t> items;
  for (size_t i = 1; i < keyframes_.size(); ++i)
    if (accepted[i] && (changed[i - 1] || changed[i])) items.push_back(i);
  std::vector<SequentialResult> side_by_side(keyframes_.size());
  RegisterSequentialAll(items, &side_by_side, "sequential edges (rectified scans)");
  int again = 0;
  for (size_t i : items) {
    Pose guess;
    RegistrationResult r;
    const bool ok = RegisteredSequential(i, side_by_side, &guess, &r);
    if (!ok) continue;  // keeps the first result
    PoseGraphEdge& e = graph_.edges[static_cast<size_t>(sequential_edge[i])];
    e.T_from_to = r.T_target_source;
    e.information = EdgeInformation(r, e.T_from_to);
    ++again;
  }
  for (size_t i = 1; i < keyframes_.size(); ++i)  // the initial estimate, chained again
    if (sequential_edge[i] >= 0)
      graph_.nodes[keyframes_[i].id] =
          graph_.nodes[keyframes_[i - 1].id] * graph_.edges[static_cast<size_t>(sequential_edge[i])].T_from_to;
  stats_.sequential_reregistered = again;
  if (again > 0) hooks_.info("pose_graph: " + std::to_string(again) + " sequential registrations redone on rectified scans");
}

std::vector<bool> Slam::RedeskewKeyframes() {
  constexpr double kMinChange = 1e-4;  // rad (0.006 deg): smaller corrections leave a scan as it is
  std::vector<bool> changed(keyframes_.size(), false);
  if (!odometry_) return changed;
  for (size_t i = 0; i < keyframes_.size(); ++i) {
    Keyframe& kf = keyframes_[i];
    const auto k = stats_.odometry_yaw_scale.find(kf.sequence);
    if (k == stats_.odometry_yaw_scale.end() || k->second == 1 || !kf.cloud.has_times()) continue;
    const double t_ref = static_cast<double>(kf.timestamp);
    std::map<int64_t, double> turn;  // odometry turn from the scan's time to each ms of it
    double largest = 0;
    std::vector<Eigen::Vector3f> points = kf.cloud.points;
    for (size_t p = 0; p < points.size(); ++p) {
      const int64_t ms = std::llround(kf.cloud.times[p] * 1000.0);
      auto it = turn.find(ms);
      if (it == turn.end())
        it = turn.emplace(ms, YawOf(odometry_->Relative(t_ref, t_ref + ms * 1e-3 / o_.seconds_per_unit))).first;
      const double delta = (k->second - 1) * it->second;
      largest = std::max(largest, std::abs(delta));
      points[p] = Eigen::AngleAxisf(static_cast<float>(delta), Eigen::Vector3f::UnitZ()) * points[p];
    }
    if (largest < kMinChange) continue;
    kf.cloud.points = std::move(points);
    kf.rough = VoxelDownsample(kf.cloud, o_.loop_rough_voxel_m);
    kf.context = MakeScanContext(kf.cloud, ScanContextOptions{});
    changed[i] = true;
  }
  return changed;
}

void Slam::CalibrateOdometryYaw(const std::map<std::string, std::vector<std::pair<size_t, double>>>& odometry_edges) {
  for (const auto& [sequence, edges] : odometry_edges) {
    std::vector<std::pair<double, double>> pairs;
    for (const auto& [index, registered] : edges) pairs.emplace_back(YawOf(graph_.edges[index].T_from_to), registered);
    const YawScaleFit fit = FitYawScale(pairs);
    stats_.odometry_yaw_scale[sequence] = fit.applied ? fit.k : 1;
    std::ostringstream line;
    line << "pose_graph: " << sequence << ": odometry turns x" << fit.k << " by " << pairs.size() << " registrations ("
         << fit.turned_rad * 180 / M_PI << " deg turned)" << (fit.applied ? "" : ": not applied");
    hooks_.info(line.str());
    if (!fit.applied) continue;
    for (const auto& [index, registered] : edges) {
      Pose& T = graph_.edges[index].T_from_to;
      const Eigen::AngleAxisd aa(T.q);
      T.q = Eigen::Quaterniond(Eigen::AngleAxisd(fit.k * aa.angle(), aa.axis()));
    }
  }
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

int Slam::AddLoopEdges() {
  std::vector<int> component(keyframes_.size());
  for (size_t i = 0; i < keyframes_.size(); ++i) component[i] = component_.at(keyframes_[i].sequence);
  LoopSearchOptions lo;
  lo.radius_m = o_.loop_radius_m;
  lo.min_travel_m = o_.loop_min_travel_m;
  lo.stride = o_.loop_stride;
  const auto candidates = LoopCandidates(keyframes_, graph_.nodes, component, lo);
  int added = 0;
  for (size_t k = 0; k < candidates.size(); ++k) {
    hooks_.check_cancelled();
    const auto [ia, ib] = candidates[k];
    // Failed candidates are tried again next round, from better estimates.
    if (accepted_.count({ia, ib})) continue;
    ++stats_.loop_tests;
    const Keyframe& a = keyframes_[ia];
    const Keyframe& b = keyframes_[ib];
    const Pose guess = graph_.nodes[a.id].Inverse() * graph_.nodes[b.id];
    const std::vector<RegistrationResult> fine = CheckLoop(a, b, {guess}, o_.loop_rough_error);
    if (!fine.empty()) {
      AddLoopEdge(a, b, fine.front());
      ++added;
    }
    hooks_.progress(k + 1, candidates.size(), "loop closures");
  }
  return added;
}

void Slam::Optimize() {
  // Every part keeps its own gauge: its first keyframe is held.
  std::set<int> fixed;
  for (const auto& [seq, c] : component_) fixed.insert(c);
  graph_.fixed.assign(fixed.begin(), fixed.end());
  PoseGraphOptions solver;
  solver.threads = threads_;
  const PoseGraphSummary s = lidar::Optimize(solver, &graph_);
  if (poses_version_ == 0) stats_.summary.initial_cost = s.initial_cost;
  stats_.summary.final_cost = s.final_cost;
  stats_.summary.iterations += s.iterations;
  stats_.summary.report = s.report;
  ++poses_version_;
}

std::shared_ptr<const Cloud> Slam::CloudOf(const Keyframe& kf) const {
  if (kf.cloud_file.empty()) return std::shared_ptr<const Cloud>(std::shared_ptr<const Cloud>(), &kf.cloud);  // not owned
  std::lock_guard<std::mutex> lock(clouds_mutex_);
  auto it = clouds_read_.find(kf.id);
  if (it == clouds_read_.end()) {
    if (o_.join_clouds_in_memory > 0 && clouds_read_.size() >= static_cast<size_t>(o_.join_clouds_in_memory)) {
      auto oldest = clouds_read_.begin();
      for (auto c = clouds_read_.begin(); c != clouds_read_.end(); ++c)
        if (c->second.first < oldest->second.first) oldest = c;
      clouds_read_.erase(oldest);  // a caller still using it keeps its own reference
    }
    it = clouds_read_.emplace(kf.id, std::make_pair(0, std::make_shared<const Cloud>(
                                                        ReadPartCloud(kf.cloud_file, kf.cloud_offset)))).first;
  }
  it->second.first = ++clouds_clock_;
  return it->second.second;
}

void Slam::AddStepTime(const std::string& step, double seconds) {
  for (auto& [name, t] : stats_.steps)
    if (name == step) {
      t += seconds;
      return;
    }
  stats_.steps.emplace_back(step, seconds);
}

namespace {

template <typename F>
auto Timed(Slam* slam, const std::string& step, F&& f) {
  const auto start = std::chrono::steady_clock::now();
  auto result = f();
  slam->AddStepTime(step, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return result;
}

}  // namespace

void Slam::Run() {
  RunWithinParts();
  RunJoins();
}

void Slam::RunWithinParts() {
  Timed(this, "sequential edges", [&] { AddSequentialEdges(); return 0; });
  before_ = graph_;
  // Each part alone first: its own loops, optimised, so that the maps
  // compared when joining are as right as they get.
  const int added = Timed(this, "loops", [&] { return AddLoopEdges(); });
  Timed(this, "optimisation", [&] { Optimize(); return 0; });
  hooks_.info("pose_graph: " + std::to_string(added) + " loop edges within the parts");
}

void Slam::RunJoins() {
  for (int round = 1; round <= o_.rounds; ++round) {
    const size_t edges = graph_.edges.size();
    const int joined = Timed(this, "joins", [&] { return JoinComponents(round); });
    Timed(this, "loops", [&] { return AddLoopEdges(); });
    const int added = static_cast<int>(graph_.edges.size() - edges);  // join loops + the others
    hooks_.info("pose_graph: round " + std::to_string(round) + ": " + std::to_string(joined) + " parts joined, " +
                std::to_string(added) + " loop edges");
    Timed(this, "optimisation", [&] { Optimize(); return 0; });
    if (added == 0 && joined == 0) break;
  }
  Timed(this, "join check", [&] { CheckFinalJoins(); return 0; });
}

SlamPart Slam::ExportPart() const {
  SlamPart part;
  part.sequence = keyframes_.front().sequence;
  for (const Keyframe& kf : keyframes_) {
    if (kf.sequence != part.sequence)
      throw Error("slam: a part holds one sequence; keyframes of " + part.sequence + " and " + kf.sequence);
    part.keyframes.push_back(kf);
  }
  part.manual = manual_.count(part.sequence) > 0;
  part.graph.nodes = graph_.nodes;
  part.graph.edges = graph_.edges;
  part.before.nodes = before_.nodes;
  part.loops.assign(accepted_.begin(), accepted_.end());
  part.stats = stats_;
  part.stats.summary.report.clear();
  return part;
}

void Slam::AdoptParts(std::vector<SlamPart> parts) {
  if (parts.empty()) throw InputError("slam: no sequence part to join");
  // The joint run's keyframe order: every scan in time order (the parts' own
  // keyframes are), ties in the order of the parts' first keyframes.
  std::stable_sort(parts.begin(), parts.end(), [](const SlamPart& a, const SlamPart& b) {
    return a.keyframes.front().timestamp < b.keyframes.front().timestamp;
  });
  std::vector<std::tuple<Timestamp, size_t, size_t>> order;  // (time, part, local id)
  for (size_t p = 0; p < parts.size(); ++p) {
    for (size_t q = 0; q < p; ++q)
      if (parts[q].sequence == parts[p].sequence)
        throw InputError("slam: two parts of sequence '" + parts[p].sequence + "'");
    for (size_t k = 0; k < parts[p].keyframes.size(); ++k) order.emplace_back(parts[p].keyframes[k].timestamp, p, k);
  }
  std::stable_sort(order.begin(), order.end(),
                   [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });
  std::vector<std::vector<int>> id(parts.size());
  for (size_t p = 0; p < parts.size(); ++p) id[p].resize(parts[p].keyframes.size());
  keyframes_.clear();
  for (const auto& [t, p, k] : order) {
    Keyframe kf = std::move(parts[p].keyframes[k]);
    kf.id = static_cast<int>(keyframes_.size());
    id[p][k] = kf.id;
    graph_.nodes[kf.id] = parts[p].graph.nodes.at(static_cast<int>(k));
    before_.nodes[kf.id] = parts[p].before.nodes.at(static_cast<int>(k));
    keyframes_.push_back(std::move(kf));
  }
  for (size_t p = 0; p < parts.size(); ++p) {
    SlamPart& part = parts[p];
    for (PoseGraphEdge e : part.graph.edges) {
      e.from = id[p].at(static_cast<size_t>(e.from));
      e.to = id[p].at(static_cast<size_t>(e.to));
      graph_.edges.push_back(e);
    }
    for (const auto& [a, b] : part.loops) {
      const int ia = id[p].at(static_cast<size_t>(a)), ib = id[p].at(static_cast<size_t>(b));
      accepted_.insert({std::min(ia, ib), std::max(ia, ib)});
    }
    if (part.manual) manual_.insert(part.sequence);
    component_[part.sequence] = part.manual ? 0 : id[p].front();
    const SlamStats& st = part.stats;
    stats_.sequential_fallbacks += st.sequential_fallbacks;
    stats_.information_fallbacks += st.information_fallbacks;
    stats_.refinements += st.refinements;
    stats_.refinements_rejected += st.refinements_rejected;
    stats_.sequential_reregistered += st.sequential_reregistered;
    stats_.loop_tests += st.loop_tests;
    for (const auto& [seq, k] : st.odometry_yaw_scale) stats_.odometry_yaw_scale[seq] = k;
    stats_.summary.initial_cost += st.summary.initial_cost;
    stats_.summary.final_cost += st.summary.final_cost;
    stats_.summary.iterations += st.summary.iterations;
    for (const auto& [step, seconds] : st.steps) AddStepTime(step, seconds);  // CPU of the parts, summed
  }
  if (o_.planar) {
    graph_.planar_sigma_z = o_.planar_sigma_z_m;
    graph_.planar_sigma_tilt = o_.planar_sigma_tilt_rad;
  }
  poses_version_ = 1;  // as after the joint run's first optimisation
  hooks_.info("pose_graph: " + std::to_string(parts.size()) + " sequence parts, " +
              std::to_string(keyframes_.size()) + " keyframes, " + std::to_string(accepted_.size()) +
              " loop edges within the parts");
}

// T_world_rig at t. Wheel odometry: the latest keyframe at or before t in
// t's odometry segment, moved by odometry (or the first keyframe, backwards).
// Constant velocity: interpolated between the keyframes around t (held at
// the nearest one outside them), within one segment.
Pose Slam::PoseAt(Timestamp t, bool* found, const Keyframe** from) const {
  const auto after = std::upper_bound(keyframes_.begin(), keyframes_.end(), t,
                                      [](Timestamp v, const Keyframe& kf) { return v < kf.timestamp; });
  const double td = static_cast<double>(t);
  const Keyframe* before = after != keyframes_.begin() ? &*(after - 1) : nullptr;
  const Keyframe* next = after != keyframes_.end() ? &*after : nullptr;
  if (!odometry_) {
    auto near = [&](const Keyframe* k) {
      return k && std::abs(static_cast<double>(t - k->timestamp)) * o_.seconds_per_unit <= o_.max_scan_gap_s;
    };
    const bool nb = near(before), nn = near(next);
    *found = nb || nn;
    if (from) *from = nb ? before : nn ? next : nullptr;
    if (nb && nn && motion_.SameSegment(before->sequence, before->timestamp, next->sequence, next->timestamp) &&
        next->timestamp > before->timestamp) {
      const double alpha =
          static_cast<double>(t - before->timestamp) / static_cast<double>(next->timestamp - before->timestamp);
      return Interpolate(graph_.nodes.at(before->id), graph_.nodes.at(next->id), alpha);
    }
    if (nb) return graph_.nodes.at(before->id);
    if (nn) return graph_.nodes.at(next->id);
    return Pose();
  }
  const bool use_before = before && odometry_->SameSegment(static_cast<double>(before->timestamp), td);
  const bool use_next = next && odometry_->SameSegment(static_cast<double>(next->timestamp), td);
  const Keyframe* best = use_before ? before : use_next ? next : nullptr;
  *found = best != nullptr;
  if (from) *from = best;
  if (!best) return Pose();
  const auto from_keyframe = [&](const Keyframe* k) {
    return graph_.nodes.at(k->id) * odometry_->Relative(static_cast<double>(k->timestamp), td);
  };
  // Between two keyframes of one sequence, the odometry forward from the one
  // before and back from the one after, blended by time: the wheels' slip
  // (~0.1 deg of yaw over a keyframe interval) is spread over the interval
  // instead of jumping at the next keyframe (a Brownian bridge).
  if (use_before && use_next && before->sequence == next->sequence && next->timestamp > before->timestamp) {
    const double alpha =
        static_cast<double>(t - before->timestamp) / static_cast<double>(next->timestamp - before->timestamp);
    return Interpolate(from_keyframe(before), from_keyframe(next), alpha);
  }
  return from_keyframe(best);
}

}  // namespace locforge::lidar

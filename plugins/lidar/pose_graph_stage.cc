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
  s.Add("dataset", &O::dataset, "Kapture recording (wheel records, rigs, camera records)").Path().Required();
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
  s.Add("sigma_translation", &O::sigma_translation, "Std of registration edges (m)").Min(1e-6);
  s.Add("sigma_rotation", &O::sigma_rotation, "Std of registration edges (deg)").Min(1e-6);
  s.Add("odometry_sigma", &O::odometry_sigma,
        "Std of odometry edges per metre driven (m/m); 0: no odometry edges").Min(0);
  s.Add("odometry_sigma_rotation", &O::odometry_sigma_rotation,
        "Rotation std of odometry edges per metre driven (deg/m)").Min(1e-6);
  s.Add("planar", &O::planar, "Level-floor prior: heights and tilts held near the first pose's");
  s.Add("planar_sigma_z", &O::planar_sigma_z, "Height std of the planar prior (m)").Min(1e-6);
  s.Add("planar_sigma_tilt", &O::planar_sigma_tilt, "Tilt std of the planar prior (deg)").Min(1e-6);
  s.Add("rounds", &O::rounds, "Loop search + optimisation rounds").Range(1, 20);
  s.Add("map_voxel", &O::map_voxel, "Voxel of the accumulated map (m)").Range(0.005, 10);
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
  double travelled = 0;  // odometry distance since the sequence start (m)
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
      : o_(o), ctx_(ctx), odometry_(WheelOdometry::FromKapture(o.dataset, o.Wheels())),
        backend_(MakeBackend(o, ctx)) {}

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
  Pose PoseAt(Timestamp t, bool* found) const;
  void WriteOutputs(const std::vector<kapture::DataRecord>& scans, const PoseGraph& before,
                    const PoseGraphSummary& summary, double seconds);

  const PoseGraphSlamOptions& o_;
  RunContext& ctx_;
  WheelOdometry odometry_;
  RegistrationBackend backend_;
  std::vector<Keyframe> keyframes_;  // sequences in time order, each in time order
  PoseGraph graph_;
  std::set<std::pair<int, int>> accepted_;  // loop edges added
  int64_t loop_tests_ = 0;
  std::set<std::pair<std::string, std::string>> joined_;  // sequences joined by a loop
  int sequential_fallbacks_ = 0;
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
    if (!odometry_.Covers(t)) continue;
    const std::string seq = SequenceOfScan(r.path);
    const bool new_sequence = !last || last->sequence != seq || !odometry_.SameSegment(last->timestamp, t);
    double travelled = 0;
    if (!new_sequence) {
      const Pose rel = odometry_.Relative(last->timestamp, t);
      const double angle = Eigen::AngleAxisd(rel.q).angle();
      if (rel.t.norm() < o_.keyframe_distance && angle < max_angle) continue;
      travelled = last->travelled + odometry_.Distance(last->timestamp, t);
    }
    Keyframe kf;
    kf.id = static_cast<int>(keyframes_.size());
    kf.timestamp = r.timestamp;
    kf.sequence = seq;
    kf.travelled = travelled;
    kf.cloud = ReadPcd(k.ExistingRecordDataPath(r.path, "sensors/records_lidar.txt"));
    kf.rough = VoxelDownsample(kf.cloud, o_.loop_rough_voxel);
    // Initial pose: sequence start (identity, or the manual correction) x odometry.
    if (new_sequence) {
      const auto c = corrections.find(seq);
      start_poses_[seq] = c != corrections.end() ? c->second : Pose();
      graph_.nodes[kf.id] = start_poses_[seq];
    } else {
      graph_.nodes[kf.id] = graph_.nodes[last->id] * odometry_.Relative(last->timestamp, t);
    }
    keyframes_.push_back(std::move(kf));
    last = &keyframes_.back();
  }
  if (keyframes_.empty()) throw InputError(scans_root.string(), 0, "records_lidar", "no scan covered by odometry");
  graph_.fixed = {0};
  if (o_.planar) {
    graph_.planar_sigma_z = o_.planar_sigma_z;
    graph_.planar_sigma_tilt = o_.planar_sigma_tilt * M_PI / 180;
  }
}

void Slam::AddSequentialEdges() {
  const Matrix6d icp_info = DiagonalInformation(o_.sigma_translation, o_.sigma_rotation * M_PI / 180);
  const Matrix6d odo_info = DiagonalInformation(5 * o_.sigma_translation, 5 * o_.sigma_rotation * M_PI / 180);
  constexpr double kMaxDeviationFromOdometry = 0.3;  // m: beyond, registration failed
  for (size_t i = 1; i < keyframes_.size(); ++i) {
    ctx_.ThrowIfCancelled();
    const Keyframe& a = keyframes_[i - 1];
    const Keyframe& b = keyframes_[i];
    if (a.sequence != b.sequence || !odometry_.SameSegment(a.timestamp, b.timestamp)) continue;
    const Pose guess = odometry_.Relative(a.timestamp, b.timestamp);
    const RegistrationResult r = backend_.Align(b.cloud, a.cloud, guess, ctx_.threads());
    PoseGraphEdge e;
    e.from = a.id;
    e.to = b.id;
    const bool ok = r.converged && r.inlier_fraction >= o_.min_overlap &&
                    (r.T_target_source.t - guess.t).norm() < kMaxDeviationFromOdometry;
    e.T_from_to = ok ? r.T_target_source : guess;
    e.information = ok ? icp_info : odo_info;
    if (!ok) ++sequential_fallbacks_;
    graph_.edges.push_back(e);
    // Odometry edge beside the registration one: constrains what scans leave
    // free (along corridors), sigma proportional to the distance driven.
    if (ok && o_.odometry_sigma > 0) {
      PoseGraphEdge odo = e;
      odo.T_from_to = guess;
      const double d = std::max(odometry_.Distance(a.timestamp, b.timestamp), 0.05);
      // Turning in place: wheel-radius and axle errors scale the turned angle (5 % here).
      const double turned = Eigen::AngleAxisd(guess.q).angle();
      odo.information = DiagonalInformation(o_.odometry_sigma * d,
                                            o_.odometry_sigma_rotation * M_PI / 180 * d + 0.05 * turned);
      graph_.edges.push_back(odo);
    }
    // Chain the initial estimate along the registered edges.
    graph_.nodes[b.id] = graph_.nodes[a.id] * e.T_from_to;
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
    if (!r.converged || r.final_error > o_.loop_rough_error) continue;
    if (!rough.converged || r.inlier_fraction > rough.inlier_fraction) rough = r;
  }
  if (!rough.converged || rough.inlier_fraction < o_.loop_rough_overlap) return false;
  if ((rough.T_target_source.t - guess.t).norm() > o_.loop_radius) return false;
  // Fine: full clouds from the rough result.
  const RegistrationResult fine = backend_.Align(b.cloud, a.cloud, rough.T_target_source, ctx_.threads());
  if (!fine.converged || fine.inlier_fraction < o_.loop_overlap) return false;
  PoseGraphEdge e;
  e.from = a.id;
  e.to = b.id;
  e.T_from_to = fine.T_target_source;
  e.information = DiagonalInformation(o_.sigma_translation, o_.sigma_rotation * M_PI / 180);
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

// T_world_rig at t: the latest keyframe at or before t in t's odometry
// segment, moved by odometry (or the first keyframe, backwards).
Pose Slam::PoseAt(Timestamp t, bool* found) const {
  // Keyframes are in time order (scans sorted by time): binary search, then
  // the neighbour at or before t, else the one after, in t's segment.
  const auto after = std::upper_bound(keyframes_.begin(), keyframes_.end(), t,
                                      [](Timestamp v, const Keyframe& kf) { return v < kf.timestamp; });
  const Keyframe* best = nullptr;
  const double td = static_cast<double>(t);
  if (after != keyframes_.begin() && odometry_.SameSegment(static_cast<double>((after - 1)->timestamp), td))
    best = &*(after - 1);
  else if (after != keyframes_.end() && odometry_.SameSegment(static_cast<double>(after->timestamp), td))
    best = &*after;
  *found = best != nullptr;
  if (!best) return Pose();
  return graph_.nodes.at(best->id) * odometry_.Relative(static_cast<double>(best->timestamp), td);
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
  kapture::Kapture dataset(o_.dataset);
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
  WriteFileAtomic(out / "trajectories.svg", TopDownSvg(plot_before, plot_after, loops));

  int loop_edges = 0, cross = 0;
  for (const auto& e : graph_.edges) {
    if (!e.loop) continue;
    ++loop_edges;
    if (keyframes_[e.from].sequence != keyframes_[e.to].sequence) ++cross;
  }
  std::set<std::string> sequences;
  for (const auto& kf : keyframes_) sequences.insert(kf.sequence);
  std::ostringstream j;
  j.precision(10);
  j << "{\n  \"scans\": " << scans.size() << ",\n  \"keyframes\": " << keyframes_.size()
    << ",\n  \"sequences\": " << sequences.size() << ",\n  \"sequential_edges\": "
    << graph_.edges.size() - loop_edges << ",\n  \"sequential_odometry_fallbacks\": " << sequential_fallbacks_
    << ",\n  \"loop_edges\": " << loop_edges << ",\n  \"cross_sequence_loop_edges\": " << cross
    << ",\n  \"loop_candidates_tested\": " << loop_tests_ << ",\n  \"initial_cost\": " << summary.initial_cost
    << ",\n  \"final_cost\": " << summary.final_cost << ",\n  \"camera_poses\": " << camera_poses
    << ",\n  \"map_points\": " << map.size() << ",\n  \"seconds\": " << seconds
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

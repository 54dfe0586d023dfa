// slam/pose_graph and slam/sequences: the stages' parameters (the SLAM's
// own, slam_options.h, plus what the stages read: the recording, the motion
// prior, the registration back-end), and the wiring of the SLAM (slam.h)
// between the scans kapture, the back-ends and the outputs (slam_output.h).
// slam/pose_graph runs the whole SLAM in one process, or, given the parts of
// slam/sequences (each sequence alone, one item each: shardable, a Slurm
// array task per sequence), only the joins over them.
#include <algorithm>
#include <chrono>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include "lidar_params.h"
#include "locforge/units.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "locforge/registration.h"
#include "slam.h"
#include "slam_part.h"
#include "slam_output.h"

namespace locforge::slam {

using namespace ::locforge::lidar;  // the library this stage wires

struct PoseGraphStageOptions {
  std::string dataset;                       // the recording (or the `recording` input)
  std::string motion_prior = "wheel";        // wheel | constant_velocity
  ComponentSpec registration{"registration/gicp"};
  WheelOverrides wheels;
  SlamOptions slam;
  static void Declare(ParamSchema<PoseGraphStageOptions>& s);
  bool Check(std::string* why) const { return slam.Check(why); }
};

class PoseGraphSlam : public Stage<PoseGraphStageOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta{"slam", "pose_graph",
                   "Pose-graph LiDAR SLAM: registration edges, coarse-to-fine loop closures, Ceres; sequences joined "
                   "only when the whole overlap confirms it",
                   {{"scans", "kapture.dataset",
                     "Undistorted platform-frame scans (lidar/preprocess, or source/pcd_keyframes)"},
                    RecordingPort(),
                    {"parts", "slam.parts",
                     "Every sequence's SLAM alone (slam/sequences, same parameters): only the joins run here",
                     LF_PORT_OPTIONAL}},
                   {{"trajectories", "kapture.trajectories",
                     "sensors/trajectories.txt: rig at every scan, cameras at every image (the first sequence's "
                     "part); map.pcd/ply, pose_graph.g2o, trajectories.svg/png, joins.csv, slam.json"}}};
    meta.version = "0.13.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

// Each sequence's keyframes, sequential and odometry edges, its own loops
// and pose graph, without the others: the first half of slam/pose_graph, one
// item per sequence. Its output feeds slam/pose_graph's `parts`.
class SequenceSlam : public PerItemStage<PoseGraphStageOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta{"slam", "sequences",
                   "Each sequence's pose-graph SLAM alone (one item per sequence): keyframes, registration and "
                   "odometry edges, its own loops, optimised; slam/pose_graph joins them (it alone reads join_*, "
                   "map_*, rounds and unjoined)",
                   {{"scans", "kapture.dataset",
                     "Undistorted platform-frame scans (lidar/preprocess, or source/pcd_keyframes)"},
                    RecordingPort()},
                   {{"parts", "slam.parts", "<sequence>.part per sequence (slam_part.h)"}}};
    meta.version = "0.1.0";
    return meta;
  }
  using PerItemStage::PerItemStage;
  std::vector<std::string> ListItems(RunContext& ctx) override;
  void ProcessItem(RunContext& ctx, const std::string& item) override;
};

void PoseGraphStageOptions::Declare(ParamSchema<PoseGraphStageOptions>& s) {
  using O = PoseGraphStageOptions;
  s.Add("dataset", &O::dataset,
        "Kapture recording (wheel records, rigs, camera records); required with motion_prior wheel").Path();
  s.Add("motion_prior", &O::motion_prior,
        "Initial guess of sequential registrations: wheel odometry, or constant velocity (no odometry; "
        "every scan a keyframe)").Choices({"wheel", "constant_velocity"});
  s.Add("registration", &O::registration,
        "Registration back-end of every registration: a stage id, or {stage: ID, params: {...}}")
      .Implements(LF_REGISTRATION_INTERFACE);
  s.AddGroup(&O::slam);  // SlamOptions::Declare (slam_options.h)
  DeclareWheelOverrides(s, &O::wheels);
}


namespace {

// The wide-gate passes' back-end: the same one with coarse_params (those it
// declares; the others are reported).
ComponentSpec WideSpec(RunContext& ctx, const PoseGraphStageOptions& o, const RegistrationBackend& refine) {
  ComponentSpec wide_spec = o.registration;
  std::string applied, skipped;
  for (const std::string& entry : o.slam.coarse_params) {
    const size_t eq = entry.find('=');
    const std::string key = entry.substr(0, eq), value = entry.substr(eq + 1);  // SlamOptions::Check: key=value
    if (!refine.Declares(key)) {
      skipped += (skipped.empty() ? "" : ", ") + key;
      continue;
    }
    wide_spec = wide_spec.With(key, value);
    applied += (applied.empty() ? "" : ", ") + entry;
  }
  if (!skipped.empty())
    ctx.Info("pose_graph: coarse_params " + skipped + " not declared by " + o.registration.stage +
             ": its wide-gate passes run to its own stop");
  if (!applied.empty()) ctx.Info("pose_graph: wide-gate passes with " + applied);
  return wide_spec;
}

// Independent registrations (sequential ones guessed by the wheels, the
// rough checks of joins) side by side: one single-threaded back-end pair
// per thread (a back-end aligns on one thread at a time). The back-ends,
// which must outlive the slam.
std::vector<RegistrationBackend> AddWorkerRegistrars(RunContext& ctx, const ComponentSpec& wide_spec,
                                                     const ComponentSpec& narrow_spec, int threads, Slam* slam) {
  std::vector<RegistrationBackend> worker_backends;
  if (threads <= 1) return worker_backends;
  std::vector<std::pair<Registrar, Registrar>> workers;
  worker_backends.reserve(2 * static_cast<size_t>(threads));
  for (int w = 0; w < threads; ++w) {
    worker_backends.push_back(RegistrationBackend::Create(ctx, wide_spec));
    worker_backends.push_back(RegistrationBackend::Create(ctx, narrow_spec));
  }
  for (int w = 0; w < threads; ++w) {
    const RegistrationBackend* wide = &worker_backends[2 * w];
    const RegistrationBackend* narrow = &worker_backends[2 * w + 1];
    workers.emplace_back([wide](const Cloud& s, const Cloud& t, const Pose& g) { return wide->Align(s, t, g, 1); },
                         [narrow](const Cloud& s, const Cloud& t, const Pose& g) { return narrow->Align(s, t, g, 1); });
  }
  slam->SetWorkerRegistrars(std::move(workers));
  return worker_backends;
}

// The scans' records in time order.
std::vector<kapture::DataRecord> ScansInTimeOrder(const kapture::Kapture& k) {
  std::vector<kapture::DataRecord> scans = k.ReadDataRecords(kapture::kSensorLidar);
  std::stable_sort(scans.begin(), scans.end(), [](const auto& a, const auto& b) { return a.timestamp < b.timestamp; });
  return scans;
}

// The keyframes of `scans` (time order), timed as the step "keyframes";
// none_is_error: see Slam::SelectKeyframes.
void SelectKeyframes(RunContext& ctx, const kapture::Kapture& k, const std::vector<kapture::DataRecord>& scans,
                     Slam* slam, bool none_is_error = true) {
  std::vector<ScanStamp> stamps;
  for (const auto& r : scans) stamps.push_back({r.timestamp, SequenceOfScan(r.path)});
  const auto keyframes_start = std::chrono::steady_clock::now();
  slam->SelectKeyframes(
      stamps, [&](size_t i) { return ReadScan(k.ExistingRecordDataPath(scans[i].path, "sensors/records_lidar.txt")); },
      none_is_error);
  slam->AddStepTime("keyframes",
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - keyframes_start).count());
  ctx.Info("pose_graph: " + std::to_string(slam->keyframes().size()) + " keyframes of " +
           std::to_string(scans.size()) + " scans");
}

// Sequences left out of the merged frame: an error with unjoined: error (or
// when a join is inconsistent), else reported.
void CheckJoins(RunContext& ctx, const Slam& slam, const SlamOptions& o) {
  bool separate = false, inconsistent = false;
  for (const auto& j : slam.sequence_joins()) {
    separate = separate || j.status == "separate";
    inconsistent = inconsistent || !j.consistent;
  }
  if (inconsistent || (separate && o.unjoined == "error")) throw Error("slam/pose_graph: " + UnjoinedMessage(slam));
  if (separate) ctx.Info("pose_graph: " + UnjoinedMessage(slam));
}

}  // namespace

namespace {

// The SLAM of a stage with its back-ends (which must outlive it) and the
// recording it reads.
struct SlamSetup {
  fs::path recording;
  std::unique_ptr<WheelOdometry> odometry;
  std::unique_ptr<RegistrationBackend> refine, backend;
  std::vector<RegistrationBackend> worker_backends;
  std::unique_ptr<Slam> slam;

  SlamSetup(RunContext& ctx, const PoseGraphStageOptions& o, const std::string& stage) {
    // The recording: wheel records (motion_prior wheel), sensors, rigs and camera records.
    const bool has_recording = ctx.HasInput("recording") || !o.dataset.empty();
    if (has_recording || o.motion_prior == "wheel") recording = RecordingOf(ctx, o.dataset, stage);
    if (o.motion_prior == "wheel")
      odometry = std::make_unique<WheelOdometry>(WheelOdometry::FromKapture(recording, o.wheels.Params()));
    // The final pass of refine_correspondence_distance_m (max_correspondence_distance
    // is a key every registration back-end declares), and the wide-gate passes.
    const bool final_pass = o.slam.refine_correspondence_distance_m > 0;
    const ComponentSpec narrow_spec =
        final_pass ? o.registration.With("max_correspondence_distance", FormatDouble(o.slam.refine_correspondence_distance_m))
                   : o.registration;
    refine = std::make_unique<RegistrationBackend>(RegistrationBackend::Create(ctx, narrow_spec));
    const ComponentSpec wide_spec = final_pass ? WideSpec(ctx, o, *refine) : o.registration;
    backend = std::make_unique<RegistrationBackend>(RegistrationBackend::Create(ctx, wide_spec));
    const int threads = ctx.threads();
    SlamHooks hooks;
    hooks.info = [&ctx](const std::string& m) { ctx.Info(m); };
    hooks.progress = [&ctx](size_t done, size_t total, const std::string& what) { ctx.Progress(done, total, what); };
    hooks.check_cancelled = [&ctx] { ctx.ThrowIfCancelled(); };
    const RegistrationBackend* wide = backend.get();
    const RegistrationBackend* narrow = refine.get();
    slam = std::make_unique<Slam>(
        o.slam, odometry.get(),
        [wide, threads](const Cloud& s, const Cloud& t, const Pose& g) { return wide->Align(s, t, g, threads); },
        [narrow, threads](const Cloud& s, const Cloud& t, const Pose& g) { return narrow->Align(s, t, g, threads); },
        threads, hooks);
    worker_backends = AddWorkerRegistrars(ctx, wide_spec, narrow_spec, threads, slam.get());
  }
};

// The item of a sequence ("" -> "_": item ids are not empty).
std::string ItemOf(const std::string& sequence) { return sequence.empty() ? "_" : sequence; }

// Parameters a part's joins may change (only the joins and the map read them).
bool JoinOnly(const std::string& key) {
  return key.rfind("join_", 0) == 0 || key.rfind("map_", 0) == 0 || key == "rounds" || key == "unjoined";
}

// The parts of `parts_dir`, refused when made with other parameters than `params`.
std::vector<SlamPart> ReadParts(RunContext& ctx, const fs::path& parts_dir,
                                const std::vector<std::pair<std::string, std::string>>& params, bool keep_clouds) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(parts_dir))
    if (e.path().extension() == ".part") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  if (files.empty()) throw InputError(parts_dir.string(), 0, "parts", "no <sequence>.part file (slam/sequences' output)");
  std::vector<SlamPart> parts;
  for (const fs::path& f : files) {
    SlamPart part = ReadSlamPart(f, keep_clouds);
    std::map<std::string, std::string> theirs(part.params.begin(), part.params.end());
    for (const auto& [key, value] : params) {
      if (JoinOnly(key)) continue;
      const auto it = theirs.find(key);
      if (it == theirs.end() || it->second != value)
        throw InputError(f.string(), 0, key,
                         "made with " + key + "=" + (it == theirs.end() ? "(absent)" : "'" + it->second + "'") +
                             ", this stage has '" + value + "': give slam/sequences and slam/pose_graph the same "
                             "parameters (only join_*, map_*, rounds and unjoined may differ)");
    }
    ctx.Info("pose_graph: part " + part.sequence + ": " + std::to_string(part.keyframes.size()) + " keyframes");
    parts.push_back(std::move(part));
  }
  return parts;
}

const ParamSchema<PoseGraphStageOptions>& Schema() {
  static const ParamSchema<PoseGraphStageOptions> schema;
  return schema;
}

}  // namespace

void PoseGraphSlam::Run(RunContext& ctx) {
  const PoseGraphStageOptions& o = options();
  const auto start = std::chrono::steady_clock::now();
  SlamSetup setup(ctx, o, "slam/pose_graph");
  Slam& slam = *setup.slam;
  const fs::path scans_root = ctx.Input("scans");
  kapture::Kapture k(scans_root);
  const std::vector<kapture::DataRecord> scans = ScansInTimeOrder(k);
  if (ctx.HasInput("parts")) {
    slam.AdoptParts(ReadParts(ctx, ctx.Input("parts"), Schema().Format(o), o.slam.join_clouds_in_memory == 0));
    slam.RunJoins();
  } else {
    SelectKeyframes(ctx, k, scans, &slam);
    slam.Run();
  }
  CheckJoins(ctx, slam, o.slam);
  // Sensors, rigs and camera records: the recording, else the scans' own.
  const kapture::Kapture dataset(setup.recording.empty() ? scans_root : setup.recording);
  ctx.Info("pose_graph: " + WriteSlamOutputs(slam, o.slam, scans, dataset, ctx.output_dir(), start));
}

std::vector<std::string> SequenceSlam::ListItems(RunContext& ctx) {
  std::set<std::string> items;
  for (const auto& r : kapture::Kapture(ctx.Input("scans")).ReadDataRecords(kapture::kSensorLidar)) {
    const std::string sequence = SequenceOfScan(r.path);
    if (sequence == "_")
      throw InputError("records_lidar.txt", 0, "sequence", "a sequence named '_' (the name of scans without one)");
    items.insert(ItemOf(sequence));
  }
  return {items.begin(), items.end()};
}

void SequenceSlam::ProcessItem(RunContext& ctx, const std::string& item) {
  const PoseGraphStageOptions& o = options();
  SlamSetup setup(ctx, o, "slam/sequences");
  kapture::Kapture k(ctx.Input("scans"));
  std::vector<kapture::DataRecord> scans;
  for (auto& r : ScansInTimeOrder(k))
    if (ItemOf(SequenceOfScan(r.path)) == item) scans.push_back(std::move(r));
  Slam& slam = *setup.slam;
  SelectKeyframes(ctx, k, scans, &slam, false);
  if (slam.keyframes().empty()) {  // as the joint run, which leaves such a sequence out
    ctx.Info("sequences: " + item + ": no scan the odometry covers: no keyframe, left out of the SLAM");
    return;
  }
  slam.RunWithinParts();
  SlamPart part = slam.ExportPart();
  part.params = Schema().Format(o);
  WriteSlamPart(ctx.output_dir() / PartFileName(part.sequence), part);
  ctx.Info("sequences: " + item + ": " + std::to_string(part.keyframes.size()) + " keyframes, " +
           std::to_string(part.loops.size()) + " loop edges");
}

LOCFORGE_REGISTER_STAGE(PoseGraphSlam)
LOCFORGE_REGISTER_STAGE(SequenceSlam)

}  // namespace locforge::slam

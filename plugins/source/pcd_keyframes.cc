// source/pcd_keyframes: a folder of LiDAR keyframes (sensor frame, already
// motion-compensated) + an optional TUM file of timestamps / reference poses
// -> the `scans` kapture read by slam/pose_graph (same layout as
// lidar/preprocess writes: device 'scan', records_data/undistorted/<seq>/).
#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "cloud.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::source {

using namespace ::locforge::lidar;  // the library this stage wires

// The i-th pose of the TUM file belongs to the i-th scan in file-name order.
struct PcdKeyframesOptions {
  std::string scans;        // folder of .pcd / .ply files
  std::string poses;        // TUM file (timestamp tx ty tz qx qy qz qw, T_world_lidar); "": none
  double period_s = 0.1;    // between scans when there is no TUM file
  std::string sequence = "seq";
  double voxel_m = 0;       // 0 keeps the points as they are
  double min_range_m = 0, max_range_m = 1e9;
  static void Declare(ParamSchema<PcdKeyframesOptions>& s) {
    using O = PcdKeyframesOptions;
    s.Add("scans", &O::scans, "Folder of keyframe clouds (.pcd/.ply, sensor frame, file-name order)")
        .Path()
        .Required();
    s.Add("poses", &O::poses,
          "TUM file: timestamps and reference poses (world <- lidar), i-th line for the i-th scan")
        .Path();
    s.Add("period_s", &O::period_s, "Seconds between scans when no TUM file is given").Range(1e-6, 1e6);
    s.Add("sequence", &O::sequence, "Sequence name (folder of the records)");
    s.Add("voxel_m", &O::voxel_m, "Voxel downsampling (m); 0: none").Range(0, 10);
    s.Add("min_range_m", &O::min_range_m, "Closer returns are dropped (m)").Min(0);
    s.Add("max_range_m", &O::max_range_m, "Farther returns are dropped (m)").Min(0);
  }
  bool Check(std::string* why) const;
};

class PcdKeyframes : public Stage<PcdKeyframesOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta{"source", "pcd_keyframes",
                   "Folder of LiDAR keyframes (+ TUM timestamps / reference poses) as a scans kapture",
                   {},
                   {{"scans", "kapture.dataset",
                     "records_lidar.txt of device 'scan' + one PCD per keyframe; trajectories.txt: the "
                     "reference poses (device rig) when a TUM file is given"}}};
    meta.version = "0.7.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

bool PcdKeyframesOptions::Check(std::string* why) const {
  if (max_range_m <= min_range_m) {
    if (why) *why = "max_range_m must be larger than min_range_m";
    return false;
  }
  if (sequence.empty() || sequence.find('/') != std::string::npos || sequence == "." || sequence == "..") {
    if (why) *why = "sequence: a plain folder name is needed";
    return false;
  }
  return true;
}

namespace {

struct TumPose {
  Timestamp timestamp;  // microseconds
  Pose T_world_lidar;
};

// TUM: "timestamp tx ty tz qx qy qz qw" per line, '#' comments.
std::vector<TumPose> ReadTumPoses(const fs::path& path) {
  std::istringstream in(ReadFile(path));
  std::vector<TumPose> out;
  std::string line;
  int64_t number = 0;
  while (std::getline(in, line)) {
    ++number;
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream s(line);
    double t, x, y, z, qx, qy, qz, qw;
    if (!(s >> t >> x >> y >> z >> qx >> qy >> qz >> qw))
      throw InputError(path.string(), number, "pose", "expected 'timestamp tx ty tz qx qy qz qw'");
    const Eigen::Quaterniond q(qw, qx, qy, qz);
    if (!std::isfinite(t) || std::abs(q.norm() - 1) > 1e-3)
      throw InputError(path.string(), number, "pose", "non-finite timestamp or non-unit quaternion");
    out.push_back({static_cast<Timestamp>(std::llround(t * 1e6)), Pose(q.normalized(), {x, y, z})});
  }
  return out;
}

}  // namespace

void PcdKeyframes::Run(RunContext& ctx) {
  const PcdKeyframesOptions& o = options();
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(o.scans)) {
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (e.is_regular_file() && (ext == ".pcd" || ext == ".ply")) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) throw InputError(o.scans, 0, "scans", "no .pcd or .ply file in the folder");
  std::vector<TumPose> poses;
  if (!o.poses.empty()) {
    poses = ReadTumPoses(o.poses);
    if (poses.size() != files.size())
      throw InputError(o.poses, 0, "poses",
                       std::to_string(poses.size()) + " poses for " + std::to_string(files.size()) +
                           " scans in " + o.scans + " (one pose per scan, in file-name order)");
    for (size_t i = 1; i < poses.size(); ++i)
      if (poses[i].timestamp <= poses[i - 1].timestamp)
        throw InputError(o.poses, 0, "timestamp", "timestamps must increase (pose " + std::to_string(i) + ")");
  }
  const fs::path out = ctx.output_dir();
  std::vector<kapture::DataRecord> records;
  kapture::Trajectories reference;
  size_t points = 0;
  for (size_t i = 0; i < files.size(); ++i) {
    ctx.ThrowIfCancelled();
    Cloud scan = ReadScan(files[i]);
    Cloud kept;
    kept.points.reserve(scan.size());
    for (const auto& p : scan.points) {
      const float r = p.norm();
      if (r >= o.min_range_m && r <= o.max_range_m) kept.points.push_back(p);
    }
    if (o.voxel_m > 0) kept = VoxelDownsample(kept, o.voxel_m);
    const Timestamp t = poses.empty() ? static_cast<Timestamp>(std::llround(i * o.period_s * 1e6)) : poses[i].timestamp;
    const std::string rel = "undistorted/" + o.sequence + "/" + files[i].stem().string() + ".pcd";
    WritePcd(out / kapture::layout::kRecordsData / rel, kept);
    records.push_back({t, "scan", rel});
    if (!poses.empty()) reference.Set(t, "rig", poses[i].T_world_lidar.Inverse());
    points += kept.size();
    ctx.Progress(i + 1, files.size(), "keyframes");
  }
  kapture::Sensors sensors;
  sensors.Add({"scan", "imported LiDAR keyframes (sensor = platform frame)", kapture::kSensorLidar, {}, {}});
  kapture::WriteSensors(out / kapture::layout::kSensors, sensors);
  kapture::Rigs rigs;
  rigs.Add("rig", {"scan", Pose(), kapture::PoseParts::kComplete, std::nullopt});
  kapture::WriteRigs(out / kapture::layout::kRigs, rigs);
  kapture::WriteRecords(out / kapture::layout::RecordsFile("lidar"), kapture::RecordKind::kLidar, records);
  if (!poses.empty()) kapture::WriteTrajectories(out / kapture::layout::kTrajectories, reference);
  ctx.Info("pcd_keyframes: " + std::to_string(files.size()) + " scans, " + std::to_string(points) + " points" +
           (poses.empty() ? std::string() : ", reference poses from " + o.poses));
}

LOCFORGE_REGISTER_STAGE(PcdKeyframes)

}  // namespace locforge::source

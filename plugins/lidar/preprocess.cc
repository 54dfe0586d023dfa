// lidar/preprocess: per reference scan, both LiDARs into the platform frame
// (rig extrinsics), each point undistorted with the odometry motion between
// its own time and the reference time (paper eq. 1:
//   p_ref = T_odom_platform(t_ref)^-1 T_odom_platform(t_i) T_platform_lidar p_i),
// range and self-hit filters, voxel downsampling, one PCD per scan.
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "cloud.h"
#include "locforge/units.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"
#include "lidar_params.h"
#include "locforge/plugin.h"
#include "wheel_odometry.h"

namespace locforge::lidar {

struct PreprocessOptions {
  std::string dataset;           // the recording (or the `recording` input)
  std::string reference_lidar;   // "": the first lidar of sensors.txt
  double voxel_m = 0.1;          // 0 disables downsampling
  double min_range_m = 0.5, max_range_m = 60;
  // Self-hit box in the platform frame: xmin ymin zmin xmax ymax zmax.
  std::vector<double> self_box_m = {-0.6, -0.45, -0.2, 0.6, 0.45, 2.3};
  double max_pair_dt_s = 0.06;   // between the merged scans of two LiDARs
  bool undistort = true;
  double seconds_per_unit = kDefaultSecondsPerUnit;
  WheelOverrides wheels;
  static void Declare(ParamSchema<PreprocessOptions>& s) {
    using O = PreprocessOptions;
    s.Add("dataset", &O::dataset, "Kapture recording (LiDAR + wheel records), or wire the recording input").Path();
    s.Add("reference_lidar", &O::reference_lidar,
          "LiDAR whose scan times are the reference; empty: the first lidar of sensors.txt");
    s.Add("voxel_m", &O::voxel_m, "Voxel size of the downsampling (m); 0: none").Range(0, 10);
    s.Add("min_range_m", &O::min_range_m, "Closer returns are dropped (m)").Min(0);
    s.Add("max_range_m", &O::max_range_m, "Farther returns are dropped (m)").Min(0);
    s.Add("self_box_m", &O::self_box_m,
          "Platform box (xmin ymin zmin xmax ymax zmax, platform frame, m): returns inside are self hits");
    s.Add("max_pair_dt_s", &O::max_pair_dt_s, "Largest time between the scans of two LiDARs merged into one (s)")
        .Range(0, 10);
    s.Add("undistort", &O::undistort, "Motion-compensate every point (paper eq. 1)");
    AddSecondsPerUnit(s, &O::seconds_per_unit);
    DeclareWheelOverrides(s, &O::wheels);
  }
  bool Check(std::string* why) const;
};

class Preprocess : public PerItemStage<PreprocessOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta{"lidar", "preprocess",
                   "LiDAR scans into the platform frame, undistorted by odometry, merged, filtered, downsampled",
                   {RecordingPort()},
                   {{"scans", "kapture.dataset",
                     "records_lidar.txt of device 'scan' (platform frame) + one PCD per reference scan, with each "
                     "point's time after the record's timestamp (field time, seconds)"}}};
    meta.version = "0.8.0";
    return meta;
  }
  using PerItemStage::PerItemStage;
  std::vector<std::string> ListItems(RunContext& ctx) override;
  void ProcessItem(RunContext& ctx, const std::string& item) override;
  void Finalize(RunContext& ctx) override;

  struct Source {
    std::string path;  // under records_data
    std::string lidar;
    Timestamp timestamp;
  };

 private:
  void Load(RunContext& ctx);
  std::mutex mutex_;
  fs::path dataset_;
  bool loaded_ = false;
  std::unique_ptr<WheelOdometry> odometry_;
  std::map<std::string, Pose> T_platform_lidar_;
  std::map<std::string, std::vector<Source>> items_;  // reference path -> scans merged
};


bool PreprocessOptions::Check(std::string* why) const {
  if (self_box_m.size() != 6) {
    if (why) *why = "self_box_m: expected 6 numbers (xmin ymin zmin xmax ymax zmax)";
    return false;
  }
  if (max_range_m <= min_range_m) {
    if (why) *why = "max_range_m must be larger than min_range_m";
    return false;
  }
  return true;
}

namespace {
constexpr const char* kScanDevice = "scan";
std::string SequenceOf(const std::string& path) {
  const size_t slash = path.find('/');
  return slash == std::string::npos ? std::string() : path.substr(0, slash);
}
std::string OutputPath(const std::string& reference_path) {
  return "undistorted/" + fs::path(reference_path).replace_extension(".pcd").generic_string();
}
}  // namespace

void Preprocess::Load(RunContext& ctx) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (loaded_) return;
  const PreprocessOptions& o = options();
  dataset_ = RecordingOf(ctx, o.dataset, "lidar/preprocess");
  kapture::Kapture k(dataset_);
  std::vector<std::string> lidars;
  for (const auto* s : k.sensors().OfType(kapture::kSensorLidar)) lidars.push_back(s->id);
  if (lidars.empty())
    throw InputError((dataset_ / kapture::layout::kSensors).string(), 0, "sensor_type",
                     "no lidar sensor");
  const std::string reference = o.reference_lidar.empty() ? lidars.front() : o.reference_lidar;
  if (std::find(lidars.begin(), lidars.end(), reference) == lidars.end())
    throw ParamError("reference_lidar '" + reference + "' is not a lidar of sensors.txt");
  for (const auto& id : lidars) {
    const kapture::Rig* rig = k.rigs().RigOf(id);
    const kapture::RigSensor* rs = rig ? rig->Find(id) : nullptr;
    // rigs.txt holds T_sensor_rig; a lidar outside any rig is the platform frame.
    T_platform_lidar_[id] = rs ? rs->sensor_from_rig.Inverse() : Pose();
  }
  std::map<std::string, std::vector<Source>> by_lidar;  // sorted by time below
  for (const auto& r : k.ReadDataRecords(kapture::kSensorLidar))
    by_lidar[r.device_id].push_back({r.path, r.device_id, r.timestamp});
  for (auto& [id, v] : by_lidar)
    std::sort(v.begin(), v.end(), [](const Source& a, const Source& b) { return a.timestamp < b.timestamp; });
  const double max_dt_units = o.max_pair_dt_s / o.seconds_per_unit;
  for (const auto& ref : by_lidar[reference]) {
    std::vector<Source>& merged = items_[ref.path];
    merged.push_back(ref);
    for (const auto& [id, scans] : by_lidar) {
      if (id == reference || scans.empty()) continue;
      auto it = std::lower_bound(scans.begin(), scans.end(), ref.timestamp,
                                 [](const Source& s, Timestamp t) { return s.timestamp < t; });
      const Source* best = nullptr;
      for (auto c : {it, it == scans.begin() ? it : it - 1}) {
        if (c == scans.end() || SequenceOf(c->path) != SequenceOf(ref.path)) continue;
        if (std::abs(static_cast<double>(c->timestamp - ref.timestamp)) > max_dt_units) continue;
        if (!best || std::abs(c->timestamp - ref.timestamp) < std::abs(best->timestamp - ref.timestamp))
          best = &*c;
      }
      if (best) merged.push_back(*best);
    }
  }
  if (o.undistort)
    odometry_ = std::make_unique<WheelOdometry>(WheelOdometry::FromKapture(dataset_, o.wheels.Params()));
  loaded_ = true;
}

std::vector<std::string> Preprocess::ListItems(RunContext& ctx) {
  Load(ctx);
  std::vector<std::string> items;
  for (const auto& [path, sources] : items_) items.push_back(path);
  return items;
}

void Preprocess::ProcessItem(RunContext& ctx, const std::string& item) {
  Load(ctx);
  const PreprocessOptions& o = options();
  const auto found = items_.find(item);
  if (found == items_.end()) throw Error("lidar/preprocess: unknown item '" + item + "'");
  kapture::Kapture k(dataset_);
  const double t_ref = static_cast<double>(found->second.front().timestamp);
  const Eigen::Vector3f box_min(o.self_box_m[0], o.self_box_m[1], o.self_box_m[2]);
  const Eigen::Vector3f box_max(o.self_box_m[3], o.self_box_m[4], o.self_box_m[5]);
  Cloud merged;
  for (const Source& src : found->second) {
    const Cloud scan = ReadScan(k.ExistingRecordDataPath(src.path, kapture::layout::RecordsFile("lidar")));
    const Pose& T_platform_lidar = T_platform_lidar_.at(src.lidar);
    // Motion from each point's time to t_ref, cached per millisecond of scan time.
    std::map<int64_t, Eigen::Matrix4f> motion;
    auto MotionAt = [&](double point_time_s) -> const Eigen::Matrix4f& {
      const int64_t ms = std::llround(point_time_s * 1000.0);
      auto it = motion.find(ms);
      if (it != motion.end()) return it->second;
      const double t = src.timestamp + ms * 1e-3 / o.seconds_per_unit;
      const Pose T_ref_t = odometry_->Relative(t_ref, t) * T_platform_lidar;
      return motion.emplace(ms, T_ref_t.Matrix().cast<float>()).first->second;
    };
    const bool timed = o.undistort && scan.has_times();
    const double scan_offset_s = (static_cast<double>(src.timestamp) - t_ref) * o.seconds_per_unit;
    const Eigen::Matrix4f fixed =
        (o.undistort ? odometry_->Relative(t_ref, static_cast<double>(src.timestamp)) * T_platform_lidar
                     : T_platform_lidar).Matrix().cast<float>();
    const Eigen::Matrix4f mount = T_platform_lidar.Matrix().cast<float>();
    for (size_t i = 0; i < scan.size(); ++i) {
      const Eigen::Vector3f& p = scan.points[i];
      const float range = p.norm();
      if (range < o.min_range_m || range > o.max_range_m) continue;
      const Eigen::Vector3f in_platform = mount.topLeftCorner<3, 3>() * p + mount.topRightCorner<3, 1>();
      if ((in_platform.array() >= box_min.array()).all() && (in_platform.array() <= box_max.array()).all())
        continue;  // self hit
      const Eigen::Matrix4f& T = timed ? MotionAt(scan.times[i]) : fixed;
      merged.points.push_back(T.topLeftCorner<3, 3>() * p + T.topRightCorner<3, 1>());
      // Its time after the output's timestamp: what a later stage needs to
      // undistort it again with a better motion (slam/pose_graph's calibrated turns).
      merged.times.push_back(scan_offset_s + (scan.has_times() ? scan.times[i] : 0.0));
    }
  }
  if (o.voxel_m > 0) merged = VoxelDownsample(merged, o.voxel_m);
  WritePcd(ctx.output_dir() / kapture::layout::kRecordsData / OutputPath(item), merged);
}

void Preprocess::Finalize(RunContext& ctx) {
  Load(ctx);
  const fs::path out = ctx.output_dir();
  kapture::Sensors sensors;
  sensors.Add({kScanDevice, "undistorted merged LiDAR scans (platform frame)", kapture::kSensorLidar, {}, {}});
  kapture::WriteSensors(out / kapture::layout::kSensors, sensors);
  kapture::Rigs rigs;
  rigs.Add("rig", {kScanDevice, Pose(), kapture::PoseParts::kComplete, std::nullopt});
  kapture::WriteRigs(out / kapture::layout::kRigs, rigs);
  std::vector<kapture::DataRecord> records;
  for (const auto& [path, sources] : items_)
    if (fs::exists(out / kapture::layout::kRecordsData / OutputPath(path)))
      records.push_back({sources.front().timestamp, kScanDevice, OutputPath(path)});
  std::sort(records.begin(), records.end(),
            [](const auto& a, const auto& b) { return a.timestamp < b.timestamp; });
  kapture::WriteRecords(out / kapture::layout::RecordsFile("lidar"), kapture::RecordKind::kLidar, records);
}

LOCFORGE_REGISTER_STAGE(Preprocess)

}  // namespace locforge::lidar

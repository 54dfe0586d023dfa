// calib/lidar_to_lidar: extrinsic of a second LiDAR w.r.t. the first by
// registration on their shared field of view, accumulated over several
// scans. Target: reference-LiDAR points of `scans` scans, undistorted into the
// platform frame at the first scan's time (odometry, paper eq. 1). Source:
// the other LiDAR's nearest scans, undistorted into its own frame at that
// time with the current extrinsic. Align(source, target) gives T_platform_lidar;
// repeated `iterations` times (the undistortion depends on the extrinsic).
#include <cmath>
#include <sstream>

#include "cloud.h"
#include "locforge/units.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"
#include "locforge/registration.h"
#include "lidar_params.h"
#include "locforge/plugin.h"
#include "wheel_odometry.h"

namespace locforge::calib {

using namespace ::locforge::lidar;  // the library this stage wires

struct LidarToLidarOptions {
  std::string dataset;           // the recording (or the `recording` input)
  std::string reference_lidar;   // "": the first lidar of sensors.txt
  std::string lidar;             // calibrated one; "": the other lidar
  int scans = 10;                // scans accumulated
  int iterations = 2;            // undistortion / registration alternations
  double voxel_m = 0.1, min_range_m = 0.5, max_range_m = 60;
  ComponentSpec registration{"registration/gicp"};
  // Start offset applied to rigs.txt (x y z in m, roll pitch yaw in deg): tests, bad CAD.
  std::vector<double> initial_offset = {0, 0, 0, 0, 0, 0};
  double seconds_per_unit = kDefaultSecondsPerUnit;
  WheelOverrides wheels;
  static void Declare(ParamSchema<LidarToLidarOptions>& s) {
    using O = LidarToLidarOptions;
    s.Add("dataset", &O::dataset, "Kapture recording with two lidars (or wire the recording input)").Path();
    s.Add("reference_lidar", &O::reference_lidar, "Reference lidar; empty: the first of sensors.txt");
    s.Add("lidar", &O::lidar, "Calibrated lidar; empty: the other one");
    s.Add("scans", &O::scans, "Scans accumulated").Range(1, 1000);
    s.Add("iterations", &O::iterations, "Undistortion / registration alternations").Range(1, 10);
    s.Add("voxel_m", &O::voxel_m, "Voxel of the accumulated clouds (m)").Range(0.01, 10);
    s.Add("min_range_m", &O::min_range_m, "Closer returns dropped (m)").Min(0);
    s.Add("max_range_m", &O::max_range_m, "Farther returns dropped (m)").Min(0);
    s.Add("registration", &O::registration, "Registration back-end: a stage id, or {stage: ID, params: {...}}")
        .Implements(LF_REGISTRATION_INTERFACE);
    s.Add("initial_offset", &O::initial_offset,
          "Offset applied to the rigs.txt extrinsic first (x y z in m, roll pitch yaw in deg)");
    AddSecondsPerUnit(s, &O::seconds_per_unit);
    DeclareWheelOverrides(s, &O::wheels);
  }
  bool Check(std::string* why) const;
};

class LidarToLidar : public Stage<LidarToLidarOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta{"calib", "lidar_to_lidar",
                   "Extrinsic of a second LiDAR w.r.t. the first by registration on their shared view",
                   {RecordingPort()},
                   {{"rig", "kapture.dataset", "sensors/rigs.txt with the calibrated extrinsic, calib.json"}}};
    meta.version = "0.7.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

bool LidarToLidarOptions::Check(std::string* why) const {
  if (initial_offset.size() == 6) return true;
  if (why) *why = "initial_offset: expected 6 numbers (x y z m, roll pitch yaw deg)";
  return false;
}

namespace {

using ScanList = std::vector<std::pair<Cloud, double>>;  // cloud, record time

// T_platform_sensor of a sensor from the rigs (identity when absent).
Pose ExtrinsicOf(const kapture::Kapture& k, const std::string& id) {
  const kapture::Rig* rig = k.rigs().RigOf(id);
  const kapture::RigSensor* rs = rig ? rig->Find(id) : nullptr;
  return rs ? rs->sensor_from_rig.Inverse() : Pose();
}

// The initial offset (x y z m, roll pitch yaw deg) applied to T_platform_initial.
Pose WithOffset(const std::vector<double>& off, const Pose& T_platform_initial) {
  const Eigen::Quaterniond dq = Eigen::AngleAxisd(off[5] * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                                Eigen::AngleAxisd(off[4] * M_PI / 180, Eigen::Vector3d::UnitY()) *
                                Eigen::AngleAxisd(off[3] * M_PI / 180, Eigen::Vector3d::UnitX());
  return Pose(dq, Eigen::Vector3d(off[0], off[1], off[2])) * T_platform_initial;
}

// Consecutive scans of the reference from the middle of the recording, one
// odometry segment, and the other LiDAR's scan nearest in time to each.
void PickScans(kapture::Kapture& k, const WheelOdometry& odometry, const std::vector<kapture::DataRecord>& refs,
               const std::vector<kapture::DataRecord>& others, int count, double* t0, ScanList* ref_scans,
               ScanList* other_scans) {
  const size_t first = refs.size() / 2;
  *t0 = static_cast<double>(refs[first].timestamp);
  for (size_t i = first; i < refs.size() && ref_scans->size() < static_cast<size_t>(count); ++i) {
    if (!odometry.SameSegment(*t0, refs[i].timestamp)) break;
    ref_scans->emplace_back(ReadScan(k.ExistingRecordDataPath(refs[i].path)), static_cast<double>(refs[i].timestamp));
    const kapture::DataRecord* best = nullptr;
    for (const auto& r : others)
      if (!best || std::abs(r.timestamp - refs[i].timestamp) < std::abs(best->timestamp - refs[i].timestamp)) best = &r;
    if (best && odometry.SameSegment(*t0, best->timestamp))
      other_scans->emplace_back(ReadScan(k.ExistingRecordDataPath(best->path)), static_cast<double>(best->timestamp));
  }
}

// The scans' points (sensor frame, per-point times) into frame F at t0, where
// F = platform for the reference, the other LiDAR (current extrinsic)
// otherwise (into_sensor), merged and downsampled.
Cloud UndistortedMerge(const ScanList& scans, const Pose& T_platform_sensor, bool into_sensor,
                       const WheelOdometry& odometry, double t0, const LidarToLidarOptions& o) {
  Cloud merged;
  const Pose back = into_sensor ? T_platform_sensor.Inverse() : Pose();
  for (const auto& [scan, t_record] : scans) {
    Cloud out;
    for (size_t i = 0; i < scan.size(); ++i) {
      const float range = scan.points[i].norm();
      if (range < o.min_range_m || range > o.max_range_m) continue;
      const double t = t_record + (scan.has_times() ? scan.times[i] : 0.0) / o.seconds_per_unit;
      const Pose T = back * odometry.Relative(t0, t) * T_platform_sensor;
      out.points.push_back((T * scan.points[i].cast<double>()).cast<float>());
    }
    merged.points.insert(merged.points.end(), out.points.begin(), out.points.end());
  }
  return VoxelDownsample(merged, o.voxel_m);
}

// Outputs: rigs.txt with the calibrated extrinsic, sensors.txt.
void WriteRigsWith(const kapture::Kapture& k, const std::string& other_id, const Pose& T_platform_other,
                   const fs::path& out) {
  kapture::Rigs rigs;
  for (const auto& rig : k.rigs().list())
    for (auto s : rig.sensors) {
      if (s.sensor_id == other_id) {
        s.sensor_from_rig = T_platform_other.Inverse();
        s.raw_rotation.reset();
      }
      rigs.Add(rig.id, s);
    }
  kapture::WriteRigs(out / kapture::layout::kRigs, rigs);
  kapture::WriteSensors(out / kapture::layout::kSensors, k.sensors());
}

std::string CalibJson(const std::string& ref_id, const std::string& other_id, size_t scans,
                      const Pose& T_platform_other, const Pose& T_platform_initial, const RegistrationResult& r) {
  const Pose change = T_platform_other * T_platform_initial.Inverse();
  std::ostringstream j;
  j.precision(10);
  j << "{\n  \"reference_lidar\": \"" << ref_id << "\",\n  \"lidar\": \"" << other_id << "\",\n  \"scans\": "
    << scans << ",\n  \"T_platform_lidar\": {\"qw\": " << T_platform_other.q.w() << ", \"qx\": "
    << T_platform_other.q.x() << ", \"qy\": " << T_platform_other.q.y() << ", \"qz\": " << T_platform_other.q.z()
    << ", \"tx\": " << T_platform_other.t.x() << ", \"ty\": " << T_platform_other.t.y() << ", \"tz\": "
    << T_platform_other.t.z() << "},\n  \"change_from_rigs_translation_m\": " << change.t.norm()
    << ",\n  \"change_from_rigs_rotation_deg\": " << RotationAngleDeg(change.q, Eigen::Quaterniond::Identity())
    << ",\n  \"inlier_fraction\": " << r.inlier_fraction << ",\n  \"final_error\": " << r.final_error << "\n}\n";
  return j.str();
}

}  // namespace

void LidarToLidar::Run(RunContext& ctx) {
  const LidarToLidarOptions& o = options();
  const fs::path dataset = RecordingOf(ctx, o.dataset, "calib/lidar_to_lidar");
  kapture::Kapture k(dataset);
  const WheelOdometry odometry = WheelOdometry::FromKapture(dataset, o.wheels.Params());
  std::vector<std::string> lidars;
  for (const auto* s : k.sensors().OfType(kapture::kSensorLidar)) lidars.push_back(s->id);
  if (lidars.size() < 2) throw InputError((dataset / kapture::layout::kSensors).string(), 0, "sensor_type", "fewer than 2 lidars");
  const std::string ref_id = o.reference_lidar.empty() ? lidars[0] : o.reference_lidar;
  const std::string other_id = o.lidar.empty() ? (lidars[0] == ref_id ? lidars[1] : lidars[0]) : o.lidar;
  const Pose T_platform_ref = ExtrinsicOf(k, ref_id);
  const Pose T_platform_initial = ExtrinsicOf(k, other_id);
  Pose T_platform_other = WithOffset(o.initial_offset, T_platform_initial);

  std::map<std::string, std::vector<kapture::DataRecord>> by_lidar;
  for (const auto& r : k.ReadDataRecords(kapture::kSensorLidar)) by_lidar[r.device_id].push_back(r);
  const auto& refs = by_lidar[ref_id];
  const auto& others = by_lidar[other_id];
  if (refs.empty() || others.empty()) throw InputError(dataset.string(), 0, "records_lidar", "no scans of " + ref_id + " or " + other_id);
  double t0 = 0;
  ScanList ref_scans, other_scans;
  PickScans(k, odometry, refs, others, o.scans, &t0, &ref_scans, &other_scans);
  const Cloud target = UndistortedMerge(ref_scans, T_platform_ref, false, odometry, t0, o);
  const RegistrationBackend backend = RegistrationBackend::Create(ctx, o.registration);
  RegistrationResult r;
  for (int it = 0; it < o.iterations; ++it) {
    const Cloud source = UndistortedMerge(other_scans, T_platform_other, true, odometry, t0, o);
    r = backend.Align(source, target, T_platform_other, ctx.threads());
    if (!r.converged) throw Error("calib/lidar_to_lidar: registration did not converge");
    T_platform_other = r.T_target_source;
  }
  WriteRigsWith(k, other_id, T_platform_other, ctx.output_dir());
  WriteFileAtomic(ctx.output_dir() / "calib.json",
                  CalibJson(ref_id, other_id, ref_scans.size(), T_platform_other, T_platform_initial, r));
}

LOCFORGE_REGISTER_STAGE(LidarToLidar)

}  // namespace locforge::calib

// calib/perturb: intrinsics and camera rotations moved away from their
// values by a deterministic amount (the start of the must-show of issue 8);
// gt/images: the camera part of a recording with poses from another node
// (the LiDAR half), as a kapture dataset the feature and matching stages read.
#include <random>
#include <sstream>

#include "common.h"
#include "stages.h"
#include "locforge/kapture/io.h"

namespace locforge::sfm_gt {
namespace {

// Indices of the named parameters of a camera model ("f", "fx", "cx"...).
std::vector<int> ParamIndices(const Camera& camera, const std::vector<std::string>& names) {
  std::vector<int> out;
  std::stringstream ss(camera.info().param_names);
  std::string name;
  for (int i = 0; std::getline(ss, name, ','); ++i) {
    name.erase(0, name.find_first_not_of(' '));
    if (std::find(names.begin(), names.end(), name) != names.end()) out.push_back(i);
  }
  return out;
}

}  // namespace

void PerturbStage::Run(RunContext& ctx) {
  const auto& o = options();
  const fs::path in = ctx.Input("poses");
  const kp::Sensors sensors = kp::ReadSensors(in / kp::layout::kSensors);
  const kp::Rigs rigs = fs::exists(in / kp::layout::kRigs) ? kp::ReadRigs(in / kp::layout::kRigs) : kp::Rigs();
  const kp::Trajectories trajectories = kp::ReadTrajectories(in / kp::layout::kTrajectories);
  std::mt19937_64 rng(static_cast<uint64_t>(o.seed));
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  kp::Sensors out_sensors;
  kp::Rigs out_rigs;
  std::map<std::string, Pose> correction;  // T_C'C: new camera frame from old, per camera
  std::ostringstream log;
  log << "# sensor_id, focal_factor, principal_point_dx_px, principal_point_dy_px, rotation_deg, axis_x, axis_y, axis_z\n";
  for (const kp::Sensor& s : sensors.list()) {
    if (!s.IsCamera() || !s.camera) {
      out_sensors.Add(s);
      continue;
    }
    // Same draws for every camera whatever it is: sign of the focal change,
    // principal point offset, rotation axis.
    const double sign = unit(rng) < 0 ? -1.0 : 1.0;
    const double dcx = o.principal_point_px * unit(rng), dcy = o.principal_point_px * unit(rng);
    Eigen::Vector3d axis(unit(rng), unit(rng), unit(rng));
    if (axis.norm() < 1e-6) axis = Eigen::Vector3d::UnitZ();
    axis.normalize();
    Camera cam = *s.camera;
    const double factor = 1.0 + sign * o.focal_percent / 100.0;
    for (int i : ParamIndices(cam, {"f", "fx", "fy"})) cam.params[i] *= factor;
    const std::vector<int> pp = ParamIndices(cam, {"cx", "cy"});
    if (pp.size() == 2) {
      cam.params[pp[0]] += dcx;
      cam.params[pp[1]] += dcy;
    }
    out_sensors.Add(kp::MakeCameraSensor(s.id, s.name, cam));
    const double angle = o.rotation_deg * M_PI / 180.0;
    // Rotation of the camera about its own centre: T_C'C = (R, 0), so
    // T_C'_rig = T_C'C T_C_rig keeps the CAD camera centre (translation of
    // T_BC fixed, paper section 3.2).
    correction[s.id] = Pose(Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis)), Eigen::Vector3d::Zero());
    log << s.id << ", " << FormatDouble(factor) << ", " << FormatDouble(pp.size() == 2 ? dcx : 0) << ", "
        << FormatDouble(pp.size() == 2 ? dcy : 0) << ", " << FormatDouble(o.rotation_deg) << ", "
        << FormatDouble(axis.x()) << ", " << FormatDouble(axis.y()) << ", " << FormatDouble(axis.z()) << "\n";
  }
  for (const kp::Rig& rig : rigs.list())
    for (kp::RigSensor rs : rig.sensors) {
      auto it = correction.find(rs.sensor_id);
      if (it != correction.end()) {
        rs.sensor_from_rig = it->second * rs.sensor_from_rig;
        rs.raw_rotation.reset();
      }
      out_rigs.Add(rig.id, rs);
    }
  // Camera poses recomputed with the perturbed extrinsics: T_C'W = T_C'C T_CW.
  kp::Trajectories out_traj;
  for (const auto& [key, pose] : trajectories.poses) {
    auto it = correction.find(key.second);
    out_traj.Set(key.first, key.second, it == correction.end() ? pose : it->second * pose);
  }
  const fs::path out = ctx.output_dir();
  fs::create_directories(out / "sensors");
  kp::WriteSensors(out / kp::layout::kSensors, out_sensors);
  if (!out_rigs.empty()) kp::WriteRigs(out / kp::layout::kRigs, out_rigs);
  kp::WriteTrajectories(out / kp::layout::kTrajectories, out_traj);
  WriteFileAtomic(out / "perturbation.txt", log.str());
  ctx.Info("perturbed " + std::to_string(correction.size()) + " cameras: focal x(1 +- " +
           FormatDouble(o.focal_percent / 100) + "), rotation " + FormatDouble(o.rotation_deg) + " deg");
}

void ImagesStage::Run(RunContext& ctx) {
  const auto& o = options();
  const fs::path in = ctx.Input("poses");
  kp::Kapture recording(o.dataset);
  const kp::Sensors sensors = kp::ReadSensors(in / kp::layout::kSensors);
  const kp::Trajectories poses = kp::ReadTrajectories(in / kp::layout::kTrajectories);
  std::vector<kp::DataRecord> records;
  int64_t unposed = 0;
  for (const auto& r : recording.ReadDataRecords(kp::kSensorCamera)) {
    if (!sensors.Find(r.device_id))
      throw InputError((in / kp::layout::kSensors).string(), 0, r.device_id, "camera of records_camera.txt missing");
    if (!poses.Find(r.timestamp, r.device_id)) {
      ++unposed;
      continue;
    }
    records.push_back(r);
  }
  if (records.empty())
    throw InputError((in / kp::layout::kTrajectories).string(), 0, "trajectories", "no image of " + o.dataset + " has a pose");
  if (unposed) ctx.Warn(std::to_string(unposed) + " images without a pose left out");
  const fs::path out = ctx.output_dir();
  fs::create_directories(out / "sensors");
  kp::WriteSensors(out / kp::layout::kSensors, sensors);
  if (fs::exists(in / kp::layout::kRigs)) kp::WriteRigs(out / kp::layout::kRigs, kp::ReadRigs(in / kp::layout::kRigs));
  kp::WriteTrajectories(out / kp::layout::kTrajectories, poses);
  kp::WriteRecords(out / kp::layout::RecordsFile(kp::kSensorCamera), kp::RecordKind::kCamera, records);
  const int64_t linked = LinkRecordData(recording, records, out);
  ctx.Info(std::to_string(linked) + " images with poses");
}

}  // namespace locforge::sfm_gt

// calib/perturb: intrinsics and camera rotations moved away from their
// values by a deterministic amount (the start of a calibration experiment).
#include <random>
#include <sstream>

#include "locforge/plugin.h"
#include "sfm_gt_common.h"
#include "locforge/kapture/io.h"

namespace locforge::calib {

using namespace ::locforge::sfm_gt;  // the library this stage wires

namespace {

struct PerturbOptions {
  double focal_percent = 3.0;       // Every focal length scaled by 1 +- this/100 (random sign).
  double rotation_deg = 1.5;        // Every camera rotated by this angle about a random axis.
  double principal_point_px = 0.0;  // Principal point moved by up to this in x and y.
  int seed = 0;                     // Signs, axes and offsets.
  static void Declare(ParamSchema<PerturbOptions>& s) {
    s.Add("focal_percent", &PerturbOptions::focal_percent, "focal lengths scaled by 1 +- this % (random sign)").Range(0, 50);
    s.Add("rotation_deg", &PerturbOptions::rotation_deg, "camera rotations (rigs.txt) turned by this angle about a random axis").Range(0, 30);
    s.Add("principal_point_px", &PerturbOptions::principal_point_px, "principal points moved by up to this (px)").Range(0, 1000);
    s.Add("seed", &PerturbOptions::seed, "random seed (signs, axes, offsets)").Min(0);
  }
};

class PerturbStage : public Stage<PerturbOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"calib", "perturb",
            "Intrinsics and camera rotations (rigs.txt) moved away from their values by fixed "
            "amounts (deterministic); camera poses recomputed with the moved extrinsics",
            {{"poses", "kapture.trajectories", "sensors.txt, rigs.txt, trajectories.txt (e.g. slam/pose_graph)"}},
            {{"trajectories", "kapture.trajectories", "perturbed sensors/rigs, camera poses; perturbation.txt"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

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
    const double angle = DegreesToRadians(o.rotation_deg);
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

LOCFORGE_REGISTER_STAGE(PerturbStage)

}  // namespace locforge::calib

// eval/calibration: refined camera poses, intrinsics and camera rotations
// against a reference (the simulator's truth), per camera group.
#include <Eigen/Geometry>
#include <cmath>
#include <regex>

#include "locforge/plugin.h"
#include "sfm_gt_common.h"
#include "locforge/kapture/io.h"

namespace locforge::eval {

using namespace ::locforge::sfm_gt;  // the library this stage wires
namespace {

struct CalibrationEvalOptions {
  std::string reference;  // Kapture with the true sensors, rigs and camera poses.
  std::vector<std::string> labels;  // One per estimate; empty: node names.
  std::vector<std::string> groups = {"industrial=ind_.*", "smartphone=phone_.*"};
  std::string alignment = "se3";
  std::string title = "Camera poses and calibration against the reference";
  static void Declare(ParamSchema<CalibrationEvalOptions>& s) {
    using O = CalibrationEvalOptions;
    s.Add("reference", &O::reference,
          "kapture with the true sensors.txt, rigs.txt and camera poses (the simulator's output), or wire the "
          "reference input").Path();
    s.Add("labels", &O::labels, "row label of each estimate (default: node names)");
    s.Add("groups", &O::groups, "camera groups NAME=REGEX on sensor ids");
    s.Add("alignment", &O::alignment, "alignment of the estimated poses: none or one SE(3) per estimate").Choices({"none", "se3"});
    s.Add("title", &O::title, "heading of calibration.md");
  }
};

class CalibrationEvalStage : public Stage<CalibrationEvalOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"eval", "calibration",
            "Camera pose RMS errors, focal errors and camera rotation errors of one or more "
            "estimates against a reference, per camera group (one table row per estimate)",
            {{"estimates", "kapture.trajectories", "refined sensors, rigs, trajectories", LF_PORT_MULTIPLE},
             {"reference", "kapture.dataset", "the reference kapture, instead of the reference parameter",
              LF_PORT_OPTIONAL}},
            {{"report", "report", "calibration.md, calibration.csv, per_camera.csv"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

struct Accumulator {
  double sum_sq = 0, max = 0;
  int n = 0;
  void Add(double v) {
    sum_sq += v * v;
    max = std::max(max, std::abs(v));
    ++n;
  }
  double Rms() const { return n ? std::sqrt(sum_sq / n) : 0.0; }
};

std::string LabelOf(const fs::path& input) {
  // Host cache folders are <node>-<16 hex>: keep the node name.
  const std::string name = input.filename().string();
  static const std::regex keyed("(.*)-[0-9a-f]{16}");
  std::smatch m;
  return std::regex_match(name, m, keyed) ? m[1].str() : name;
}

struct Metrics {
  Accumulator position_m, rotation_deg, focal_percent, principal_point_px, camera_rotation_deg;
  Accumulator position_raw_m, position_sim3_m;  // no alignment; Sim(3) alignment
  int cameras = 0;
};

}  // namespace

// SE(3) aligning estimated camera poses to reference ones (T_refworld_estworld):
// rotation = the chordal mean of the per-image R_ref^T R_est (uses the
// orientations, so it stays well-posed when the camera centres are nearly
// collinear), translation = mean of c_ref - R c_est.
Pose AlignPoses(const std::vector<Pose>& est, const std::vector<Pose>& ref) {
  Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < est.size(); ++i) sum += ref[i].R().transpose() * est[i].R();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(sum, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) d(2, 2) = -1;
  const Eigen::Matrix3d R = svd.matrixU() * d * svd.matrixV().transpose();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < est.size(); ++i) t += ref[i].Center() - R * est[i].Center();
  if (!est.empty()) t /= static_cast<double>(est.size());
  return Pose(Eigen::Quaterniond(R), t);
}

struct Sim3Alignment {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  double scale = 1;
  Eigen::Vector3d t = Eigen::Vector3d::Zero();  // c_ref = scale * R * c_est + t
};

// Sim(3) aligning estimated camera centres to reference ones: rotation as in
// AlignPoses, then the scale s and translation t minimising
// sum |s R c_est + t - c_ref|^2 (closed form for a fixed R).
Sim3Alignment AlignSim3(const std::vector<Pose>& est, const std::vector<Pose>& ref) {
  Sim3Alignment a;
  a.R = AlignPoses(est, ref).R();
  if (est.empty()) return a;
  Eigen::Vector3d me = Eigen::Vector3d::Zero(), mr = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < est.size(); ++i) {
    me += est[i].Center();
    mr += ref[i].Center();
  }
  me /= static_cast<double>(est.size());
  mr /= static_cast<double>(est.size());
  double num = 0, den = 0;
  for (size_t i = 0; i < est.size(); ++i) {
    const Eigen::Vector3d x = a.R * (est[i].Center() - me);
    num += x.dot(ref[i].Center() - mr);
    den += x.squaredNorm();
  }
  a.scale = den > 0 ? num / den : 1.0;
  a.t = mr - a.scale * a.R * me;
  return a;
}

namespace {

// The reference's sensors, rigs and camera poses.
struct Reference {
  kp::Sensors sensors;
  kp::Rigs rigs;
  kp::Trajectories traj;
};

// A camera pose with a reference pose at the same (timestamp, device).
struct PosePair {
  std::string device;
  Pose est, ref;
};

std::vector<PosePair> PosePairs(const fs::path& input, const kp::Sensors& sensors, const Reference& reference,
                                const std::string& reference_name) {
  const kp::Trajectories traj = kp::ReadTrajectories(input / kp::layout::kTrajectories);
  std::vector<PosePair> pairs;
  for (const auto& [key, pose] : traj.poses) {
    const kp::Sensor* s = sensors.Find(key.second);
    if (!s || !s->IsCamera()) continue;
    const Pose* ref = reference.traj.Find(key.first, key.second);
    if (ref) pairs.push_back({key.second, pose, *ref});
  }
  if (pairs.empty())
    throw InputError((input / kp::layout::kTrajectories).string(), 0, "trajectories",
                     "no camera pose shares a (timestamp, device) with " + reference_name);
  return pairs;
}

// Each pose's position and rotation errors after the SE(3) alignment
// T_ref_est, without alignment and after the Sim(3) one, by group and by camera.
void AddPoseErrors(const std::vector<PosePair>& pairs, const Pose& T_ref_est, const Sim3Alignment& sim3,
                   const CameraGroups& groups, std::map<std::string, Metrics>* metrics,
                   std::map<std::string, Metrics>* camera_poses) {
  for (const auto& p : pairs) {
    const Pose est = p.est * T_ref_est.Inverse();  // T_C_refworld
    const double dp = (est.Center() - p.ref.Center()).norm();
    const double dr = RotationAngleDeg(est.q, p.ref.q);
    const double dp_raw = (p.est.Center() - p.ref.Center()).norm();
    const double dp_sim3 = (sim3.scale * sim3.R * p.est.Center() + sim3.t - p.ref.Center()).norm();
    for (const std::string& g : {groups.Of(p.device), std::string("all")}) {
      (*metrics)[g].position_m.Add(dp);
      (*metrics)[g].rotation_deg.Add(dr);
      (*metrics)[g].position_raw_m.Add(dp_raw);
      (*metrics)[g].position_sim3_m.Add(dp_sim3);
    }
    (*camera_poses)[p.device].position_m.Add(dp);
    (*camera_poses)[p.device].rotation_deg.Add(dr);
  }
}

// Each camera's intrinsics and rotation to the rig against the reference's:
// into the group metrics and one row of the per-camera table.
void AddCameraErrors(const std::string& label, const kp::Sensors& sensors, const kp::Rigs& rigs,
                     const Reference& reference, const CameraGroups& groups,
                     std::map<std::string, Metrics>* metrics, std::map<std::string, Metrics>& camera_poses,
                     TextTable* per_camera) {
  for (const kp::Sensor& s : sensors.list()) {
    if (!s.IsCamera() || !s.camera) continue;
    const kp::Sensor* r = reference.sensors.Find(s.id);
    if (!r || !r->camera) continue;
    const double fe = 100.0 * (0.5 * (s.camera->fx() / r->camera->fx() + s.camera->fy() / r->camera->fy()) - 1.0);
    const double ppe = std::hypot(s.camera->cx() - r->camera->cx(), s.camera->cy() - r->camera->cy());
    double rot = std::nan("");
    const kp::Rig* rig = rigs.RigOf(s.id);
    const kp::Rig* ref_rig = reference.rigs.RigOf(s.id);
    if (rig && ref_rig)
      rot = RotationAngleDeg(rig->Find(s.id)->sensor_from_rig.q, ref_rig->Find(s.id)->sensor_from_rig.q);
    const std::string g = groups.Of(s.id);
    for (const std::string& k : {g, std::string("all")}) {
      Metrics& m = (*metrics)[k];
      ++m.cameras;
      m.focal_percent.Add(fe);
      m.principal_point_px.Add(ppe);
      if (!std::isnan(rot)) m.camera_rotation_deg.Add(rot);
    }
    const Metrics& cp = camera_poses[s.id];
    per_camera->rows.push_back({label, s.id, g, Fixed(fe, 3), Fixed(ppe, 2), std::isnan(rot) ? "-" : Fixed(rot, 3),
                                std::to_string(cp.position_m.n), Fixed(100 * cp.position_m.Rms(), 2),
                                Fixed(cp.rotation_deg.Rms(), 3)});
  }
}

// One row per group with poses or cameras, then "all".
void AddGroupRows(const std::string& label, const std::vector<std::string>& group_names,
                  std::map<std::string, Metrics>& metrics, const Sim3Alignment& sim3, TextTable* table) {
  for (const std::string& g : group_names) {
    const Metrics& m = metrics[g];
    if (!m.position_m.n && !m.cameras) continue;
    table->rows.push_back({label + (g == "all" ? "" : " / " + g), std::to_string(m.cameras),
                           std::to_string(m.position_m.n), Fixed(100 * m.position_m.Rms(), 2),
                           Fixed(m.rotation_deg.Rms(), 3), Fixed(100 * m.position_raw_m.Rms(), 2),
                           Fixed(100 * m.position_sim3_m.Rms(), 2), Fixed(100 * (sim3.scale - 1), 3),
                           Fixed(m.focal_percent.Rms(), 3),
                           Fixed(m.focal_percent.max, 3), Fixed(m.principal_point_px.Rms(), 2),
                           Fixed(m.camera_rotation_deg.Rms(), 3), Fixed(m.camera_rotation_deg.max, 3)});
  }
}

// One estimate's rows of both tables.
void EvaluateEstimate(const std::string& label, const fs::path& input, const Reference& reference,
                      const CalibrationEvalOptions& o, const CameraGroups& groups,
                      const std::vector<std::string>& group_names, TextTable* table, TextTable* per_camera) {
  const kp::Sensors sensors = kp::ReadSensors(input / kp::layout::kSensors);
  const kp::Rigs rigs = fs::exists(input / kp::layout::kRigs) ? kp::ReadRigs(input / kp::layout::kRigs) : kp::Rigs();
  const std::vector<PosePair> pairs = PosePairs(input, sensors, reference, o.reference);
  Pose T_ref_est;
  std::vector<Pose> a, b;
  for (const auto& p : pairs) {
    a.push_back(p.est);
    b.push_back(p.ref);
  }
  if (o.alignment == "se3") T_ref_est = AlignPoses(a, b);
  const Sim3Alignment sim3 = AlignSim3(a, b);
  std::map<std::string, Metrics> metrics;       // group -> metrics
  std::map<std::string, Metrics> camera_poses;  // camera -> pose metrics
  AddPoseErrors(pairs, T_ref_est, sim3, groups, &metrics, &camera_poses);
  AddCameraErrors(label, sensors, rigs, reference, groups, &metrics, camera_poses, per_camera);
  AddGroupRows(label, group_names, metrics, sim3, table);
}

}  // namespace

void CalibrationEvalStage::Run(RunContext& ctx) {
  const auto& o = options();
  const CameraGroups groups = CameraGroups::Parse(o.groups);
  const fs::path ref_root = ctx.PathOrInput("eval/calibration", "reference", o.reference, "reference");
  const Reference reference{kp::ReadSensors(ref_root / kp::layout::kSensors),
                            kp::ReadRigs(ref_root / kp::layout::kRigs),
                            kp::ReadTrajectories(ref_root / kp::layout::kTrajectories)};
  const std::vector<fs::path> inputs = ctx.Inputs("estimates");
  if (!o.labels.empty() && o.labels.size() != inputs.size())
    throw ParamError("labels: " + std::to_string(o.labels.size()) + " given for " +
                     std::to_string(inputs.size()) + " estimates");
  std::vector<std::string> group_names;
  for (const auto& g : groups.groups) group_names.push_back(g.first);
  group_names.push_back("all");

  TextTable table;
  // position/rotation RMS: after the `alignment` (SE(3) by default).
  table.header = {"estimate", "cameras", "images", "position RMS (cm)", "rotation RMS (deg)",
                  "position RMS no alignment (cm)", "position RMS Sim(3) (cm)", "Sim(3) scale - 1 (%)",
                  "focal error RMS (%)", "focal error max (%)", "principal point RMS (px)",
                  "camera rotation RMS (deg)", "camera rotation max (deg)"};
  TextTable per_camera;
  per_camera.header = {"estimate", "camera", "group", "focal error (%)", "principal point error (px)",
                       "camera rotation error (deg)", "images", "position RMS (cm)", "rotation RMS (deg)"};
  for (size_t e = 0; e < inputs.size(); ++e)
    EvaluateEstimate(o.labels.empty() ? LabelOf(inputs[e]) : o.labels[e], inputs[e], reference, o, groups,
                     group_names, &table, &per_camera);
  const fs::path out = ctx.output_dir();
  const std::string note =
      "Camera poses: per image, against the reference pose of the same (timestamp, camera); " +
      std::string(o.alignment == "se3" ? "after one SE(3) alignment per estimate (rotation: chordal mean of the per-image rotation differences; translation: mean centre difference)"
                                       : "without alignment") +
      "; also without any alignment (the LiDAR half fixes the first pose of the first sequence to the "
      "reference's frame) and after one Sim(3) alignment of the camera centres (rotation as for SE(3), "
      "then least-squares scale and translation; its scale - 1 is listed). Focal error: mean of fx and fy relative errors. Camera rotation: angle between the "
      "estimated and reference rotation of T_camera_rig (rigs.txt).\n\n";
  WriteFileAtomic(out / "calibration.md", "# " + o.title + "\n\n" + note + table.Markdown() +
                                              "\n## Per camera\n\n" + per_camera.Markdown());
  WriteFileAtomic(out / "calibration.csv", table.Csv());
  WriteFileAtomic(out / "per_camera.csv", per_camera.Csv());
  ctx.Info("\n" + table.Markdown());
}

LOCFORGE_REGISTER_STAGE(CalibrationEvalStage)

}  // namespace locforge::eval

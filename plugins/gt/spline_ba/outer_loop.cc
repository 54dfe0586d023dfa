#include "outer_loop.h"

#include <chrono>
#include <cmath>
#include <set>
#include <sstream>

#include "locforge/colmap/convert.h"
#include "locforge/colmap/run.h"
#include "locforge/kapture/io.h"

namespace locforge::sfm_gt {

namespace kp = locforge::kapture;

namespace {
using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
}  // namespace

bool OuterLoopOptions::Check(std::string* why) const {
  if (filter_max_reproj_error.empty()) return *why = "filter_max_reproj_error: give at least one value", false;
  for (double v : filter_max_reproj_error)
    if (!(v > 0)) return *why = "filter_max_reproj_error: values must be > 0", false;
  if (const std::string ba_why = ba.CheckMessage(); !ba_why.empty())
    return *why = "spline bundle adjustment options: " + ba_why, false;
  return true;
}

ReprojStats MeanReprojection(const colmap::Reconstruction& model, const State& state,
                             const std::map<colmap::CameraId, std::string>& sensor_of) {
  std::map<colmap::ImageId, const colmap::ModelImage*> images;
  for (const auto& im : model.images) images[im.image_id] = &im;
  double sum = 0;
  int64_t n = 0;
  for (const auto& p : model.points3d)
    for (const auto& t : p.track) {
      const colmap::ModelImage* im = images.at(t.image_id);
      const auto& is = state.images.at(im->name);
      const Camera& cam = state.cameras.at(sensor_of.at(im->camera_id)).camera;
      const Eigen::Vector3d pc = is.T_cam_world * p.xyz;
      if (pc.z() <= 0) continue;
      sum += (cam.Project(pc) - im->points2d.at(t.point2d_idx).xy).norm();
      ++n;
    }
  return {n ? sum / n : 0.0, n};
}

sfm::BAProblem BuildProblem(const colmap::Reconstruction& model, const State& state,
                            const std::map<colmap::CameraId, std::string>& sensor_of,
                            const OuterLoopOptions& o, Timestamp t0, ProblemIndex* index) {
  sfm::BAProblem problem;
  const double spu = o.seconds_per_unit;
  const auto margin = static_cast<Timestamp>(std::llround(0.5 / spu));  // 0.5 s beyond the ends
  for (const RigSequence& seq : state.sequences) {
    sfm::BAProblem::Trajectory tr;
    for (size_t i = 0; i < seq.timestamps.size(); ++i) {
      tr.times_s.push_back(static_cast<double>(seq.timestamps[i] - t0) * spu);
      tr.T_world_body.push_back(seq.T_world_rig[i]);
    }
    problem.trajectories.push_back(std::move(tr));
  }
  std::map<std::string, int> sensor_index;
  for (const auto& [id, cs] : state.cameras) {
    sfm::BAProblem::Sensor s;
    s.camera = cs.camera;
    s.T_body_camera = cs.T_cam_rig ? cs.T_cam_rig->Inverse() : Pose();
    s.calibrate_intrinsics = o.ba.calibrate_intrinsics;
    s.calibrate_rotation = o.ba.calibrate_rotations && cs.T_cam_rig.has_value();
    s.time_offset_s = cs.time_offset_s;
    sensor_index[id] = static_cast<int>(problem.sensors.size());
    index->sensor_ids.push_back(id);
    problem.sensors.push_back(std::move(s));
  }
  std::map<colmap::ImageId, int> image_index;
  for (const auto& im : model.images) {
    const auto& is = state.images.at(im.name);
    const int seq = SequenceOf(state.sequences, is.timestamp, margin);
    if (seq < 0 || !state.cameras.at(is.device).T_cam_rig) {
      ++index->skipped_images;
      continue;
    }
    sfm::BAProblem::Image image;
    image.trajectory = seq;
    image.sensor = sensor_index.at(sensor_of.at(im.camera_id));
    image.time_s = static_cast<double>(is.timestamp - t0) * spu;
    image.T_world_camera = is.T_cam_world.Inverse();
    image.name = im.name;
    image_index[im.image_id] = static_cast<int>(problem.images.size());
    index->image_names.push_back(im.name);
    problem.images.push_back(std::move(image));
  }
  std::map<colmap::ImageId, const colmap::ModelImage*> images;
  for (const auto& im : model.images) images[im.image_id] = &im;
  for (const auto& p : model.points3d) {
    std::vector<sfm::BAProblem::Observation> obs;
    for (const auto& t : p.track) {
      auto it = image_index.find(t.image_id);
      if (it == image_index.end()) continue;
      obs.push_back({it->second, static_cast<int>(problem.points.size()),
                     images.at(t.image_id)->points2d.at(t.point2d_idx).xy});
    }
    if (obs.size() < 2) continue;
    sfm::BAProblem::Point point;
    point.xyz = p.xyz;
    problem.points.push_back(point);
    problem.observations.insert(problem.observations.end(), obs.begin(), obs.end());
  }
  return problem;
}

PoseChange Compare(const State& a, const State& b) {
  double sp = 0, sr = 0;
  int n = 0;
  for (const auto& [name, ia] : a.images) {
    const auto& ib = b.images.at(name);
    sp += (ia.T_cam_world.Center() - ib.T_cam_world.Center()).squaredNorm();
    const double r = RotationAngleDeg(ia.T_cam_world.q, ib.T_cam_world.q);
    sr += r * r;
    ++n;
  }
  return {n ? std::sqrt(sp / n) : 0.0, n ? std::sqrt(sr / n) : 0.0};
}

bool Converged(const OuterLoopOptions& o, bool last_threshold, const PoseChange& change,
               double last_reproj, double reproj) {
  return last_threshold && last_reproj >= 0 && change.position_m < o.pose_tolerance_m &&
         change.rotation_deg < o.rotation_tolerance_deg &&
         std::abs(reproj - last_reproj) < o.reproj_tolerance_px;
}

// COLMAP reads the images for point colours only: the map's images, else an
// empty folder (grey points).
fs::path OuterLoop::ImagePath() const {
  const fs::path images = map_->root() / kp::layout::kRecordsData;
  if (fs::is_directory(images)) return images;
  fs::create_directories(out_ / "no_images");
  return out_ / "no_images";
}

void OuterLoop::LoadInputs() {
  map_ = std::make_unique<kp::Kapture>(ctx_.Input("map"));
  features_ = std::make_unique<kp::Kapture>(ctx_.Input("features"));
  matches_ = std::make_unique<kp::Kapture>(ctx_.Input("matches"));
  type_ = colmap::KeypointsType(*features_, o_.keypoints_type);
  const std::string traj_file = (map_->root() / kp::layout::kTrajectories).string();
  for (const kp::Sensor* s : map_->sensors().OfType(kp::kSensorCamera)) {
    State::CameraState cs;
    cs.camera = *s->camera;
    const kp::Rig* rig = map_->rigs().RigOf(s->id);
    if (rig) cs.T_cam_rig = rig->Find(s->id)->sensor_from_rig;
    state_.cameras[s->id] = cs;
  }
  for (const auto& r : map_->ReadDataRecords(kp::kSensorCamera)) {
    const Pose* pose = map_->trajectories().Find(r.timestamp, r.device_id);
    if (!pose) continue;
    state_.images[r.path] = {r.device_id, r.timestamp, *pose};
  }
  if (state_.images.empty()) throw InputError(traj_file, 0, "trajectories", "no image has a pose");
  const auto gap = static_cast<Timestamp>(std::llround(o_.sequence_gap_s / o_.seconds_per_unit));
  state_.sequences = SplitRigSequences(map_->trajectories(), o_.rig, gap);
  if (state_.sequences.empty())
    throw InputError(traj_file, 0, o_.rig, "no pose of the rig device '" + o_.rig + "' (platform trajectory)");
  t0_ = state_.sequences.front().timestamps.front();
  for (const auto& seq : state_.sequences) fitted_.push_back(seq.T_world_rig);
  ctx_.Info(std::to_string(state_.images.size()) + " posed images, " + std::to_string(state_.cameras.size()) +
            " cameras, " + std::to_string(state_.sequences.size()) + " platform trajectories");
}

void OuterLoop::BuildDatabase() {
  const fs::path db_path = out_ / "database.db";
  fs::remove(db_path);
  colmap::Database db(db_path, colmap::Database::Mode::kCreate);
  colmap::DatabaseWriter writer(&db);
  ids_ = colmap::AddImages(*map_, *features_, type_, &writer);
  const int64_t pairs = colmap::AddMatches(*matches_, type_, ids_.id_of, {}, &writer);
  writer.Finish();
  for (const auto& [sensor, id] : ids_.camera_of) sensor_of_[id] = sensor;
  ctx_.Info("database: " + std::to_string(ids_.id_of.size()) + " images, " + std::to_string(pairs) + " matched pairs");
}

// point_triangulator on a fixed-pose model of the current state.
colmap::Reconstruction OuterLoop::Triangulate(double threshold, const std::string& name) {
  const fs::path work = out_ / "rounds" / name;
  fs::create_directories(work / "model");
  colmap::Reconstruction input;
  double f_min = 1e18;
  for (const auto& [sensor, camera_id] : ids_.camera_of) {
    input.cameras.push_back({camera_id, state_.cameras.at(sensor).camera});
    f_min = std::min(f_min, std::min(state_.cameras.at(sensor).camera.fx(), state_.cameras.at(sensor).camera.fy()));
  }
  for (const auto& [image_name, is] : state_.images) {
    auto id = ids_.id_of.find(image_name);
    if (id == ids_.id_of.end()) continue;
    colmap::ModelImage image;
    image.image_id = id->second;
    image.camera_id = ids_.camera_of.at(is.device);
    image.name = image_name;
    image.SetCameraFromWorld(is.T_cam_world);
    const auto kpts = features_->ReadKeypoints(type_, image_name);
    image.points2d.resize(kpts.rows);
    for (int64_t i = 0; i < kpts.rows; ++i) image.points2d[i].xy = Eigen::Vector2d(kpts.At(i, 0), kpts.At(i, 1));
    input.images.push_back(std::move(image));
  }
  colmap::WriteModelText(input, work / "input_model");
  // Triangulation thresholds follow the filter threshold: an angular error
  // of `threshold` px at the smallest focal length, at least COLMAP's 2 deg.
  const double angle_deg = std::max(2.0, std::atan(threshold / f_min) * 180.0 / M_PI);
  std::vector<std::string> args = {"point_triangulator", "--database_path", (out_ / "database.db").string(),
                                   "--input_path", (work / "input_model").string(),
                                   "--output_path", (work / "model").string(), "--clear_points", "1",
                                   "--image_path", ImagePath().string()};
  for (const char* n : {"ba_refine_focal_length", "ba_refine_principal_point", "ba_refine_extra_params"})
    colmap::AddMapperOption(&args, n, 0);
  colmap::AddMapperOption(&args, "min_num_matches", o_.min_num_matches);
  colmap::AddMapperOption(&args, "filter_max_reproj_error", threshold);
  colmap::AddMapperOption(&args, "tri_merge_max_reproj_error", threshold);
  colmap::AddMapperOption(&args, "tri_complete_max_reproj_error", threshold);
  colmap::AddMapperOption(&args, "tri_create_max_angle_error", angle_deg);
  colmap::AddMapperOption(&args, "tri_continue_max_angle_error", angle_deg);
  colmap::AddMapperOption(&args, "tri_re_max_angle_error", std::max(5.0, angle_deg));
  colmap::RunOptions ro;
  ro.log_file = work / "colmap_point_triangulator.log";
  ro.timeout_s = o_.timeout_s;
  ro.cancelled = [this] { return ctx_.cancelled(); };  // Ctrl-C stops colmap too
  colmap::RunColmap(args, ro);
  return colmap::ReadModel(work / "model");
}

// One round: triangulation at `threshold`, then the bundle adjustment,
// whose refined values are written back into the state.
OuterLoop::RoundResult OuterLoop::RunRound(int round, double threshold) {
  const auto t_tri = Clock::now();
  const colmap::Reconstruction model = Triangulate(threshold, "round_" + std::to_string(round));
  const double tri_s = Since(t_tri);
  const ReprojStats before = MeanReprojection(model, state_, sensor_of_);
  ProblemIndex index;
  sfm::BAProblem problem = BuildProblem(model, state_, sensor_of_, o_, t0_, &index);
  if (problem.observations.empty())
    throw InputError(ctx_.Input("matches").string(), 0, "matches",
                     "round " + std::to_string(round) + ": triangulation gave no point seen twice");
  sfm::SplineBAOptions ba = o_.ba;
  ba.num_threads = ctx_.threads();
  ba.cancelled = [this] { return ctx_.cancelled(); };
  if (!ba.Check()) throw ParamError("spline bundle adjustment options: " + ba.CheckMessage());
  const auto t_ba = Clock::now();
  const sfm::SplineBAResult result = sfm::RunSplineBA(ba, &problem);
  const double ba_s = Since(t_ba);
  if (result.cancelled) throw Cancelled();
  if (!result.usable)
    throw Error("round " + std::to_string(round) + ": spline bundle adjustment failed: " + result.message);
  // Write the refined values back.
  const State previous = state_;
  for (size_t i = 0; i < problem.images.size(); ++i)
    state_.images.at(index.image_names[i]).T_cam_world = problem.images[i].T_world_camera.Inverse();
  for (size_t s = 0; s < problem.sensors.size(); ++s) {
    auto& cs = state_.cameras.at(index.sensor_ids[s]);
    cs.camera = problem.sensors[s].camera;
    cs.time_offset_s = problem.sensors[s].time_offset_s;
    if (cs.T_cam_rig) cs.T_cam_rig = problem.sensors[s].T_body_camera.Inverse();
  }
  // The fitted splines are the output; every round starts its splines (and
  // their weak prior) from the LiDAR poses again, so the map frame cannot
  // drift from round to round.
  for (size_t q = 0; q < problem.trajectories.size(); ++q)
    fitted_[q] = problem.trajectories[q].T_world_body;
  alignments_ = result.trajectory_alignments;
  scales_ = result.trajectory_scales;
  const PoseChange change = Compare(previous, state_);
  const double after = result.final_mean_reproj_px;
  ctx_.Info("round " + std::to_string(round) + ": filter " + FormatDouble(threshold) + " px, " +
            std::to_string(model.points3d.size()) + " points, reproj " + Fixed(before.mean_px, 3) + " -> " +
            Fixed(after, 3) + " px, pose change " + Fixed(100 * change.position_m, 3) + " cm / " +
            Fixed(change.rotation_deg, 4) + " deg; BA: " + result.message +
            (index.skipped_images ? ", " + std::to_string(index.skipped_images) + " images outside every trajectory" : ""));
  rounds_.rows.push_back({std::to_string(round), FormatDouble(threshold), std::to_string(problem.images.size()),
                          std::to_string(problem.points.size()), std::to_string(problem.observations.size()),
                          Fixed(before.mean_px, 3), Fixed(after, 3), Fixed(100 * change.position_m, 3),
                          Fixed(change.rotation_deg, 4), std::to_string(result.iterations),
                          result.converged ? "yes" : "no", Fixed(tri_s, 1), Fixed(ba_s, 1)});
  return {after, change};
}

void OuterLoop::Run() {
  const auto start = Clock::now();
  LoadInputs();
  BuildDatabase();
  rounds_.header = {"round", "filter (px)", "images", "points", "observations", "reproj before (px)",
                    "reproj after (px)", "pose change (cm)", "rotation change (deg)", "BA iterations",
                    "BA converged", "triangulation (s)", "BA (s)"};
  const State initial = state_;
  double last_reproj = -1;
  bool converged = false;
  int rounds_done = 0;
  for (int round = 0; round < o_.rounds && !converged; ++round) {
    ctx_.ThrowIfCancelled();
    const size_t k = std::min<size_t>(round, o_.filter_max_reproj_error.size() - 1);
    const RoundResult r = RunRound(round, o_.filter_max_reproj_error[k]);
    ++rounds_done;
    converged = Converged(o_, k + 1 == o_.filter_max_reproj_error.size(), r.change, last_reproj, r.after_px);
    last_reproj = r.after_px;
  }
  // The SfM model of the final poses and intrinsics.
  const auto t_final = Clock::now();
  const colmap::Reconstruction model =
      Triangulate(o_.filter_max_reproj_error.back(), "final");
  const ReprojStats final_reproj = MeanReprojection(model, state_, sensor_of_);
  const PoseChange total = Compare(initial, state_);
  ctx_.Info("final model: " + std::to_string(model.images.size()) + " images, " +
            std::to_string(model.points3d.size()) + " points, mean reprojection " +
            Fixed(final_reproj.mean_px, 3) + " px (" + Fixed(Since(t_final), 1) + " s)");
  WriteOutputs(model);
  WriteReports(model, final_reproj, total, converged, rounds_done, start);
}

void OuterLoop::WriteReports(const colmap::Reconstruction& model, const ReprojStats& final_reproj,
                             const PoseChange& total, bool converged, int rounds_done,
                             std::chrono::steady_clock::time_point start) {
  // Table 4 of the paper for this run.
  TextTable t4;
  t4.header = {"images", "points", "mean observations per image", "mean reprojection error (px)"};
  t4.rows.push_back({std::to_string(model.images.size()), std::to_string(model.points3d.size()),
                     Fixed(model.MeanObservationsPerImage(), 1), Fixed(final_reproj.mean_px, 3)});
  WriteFileAtomic(out_ / "table4.md", "# SfM model (the paper's Table 4)\n\n" + t4.Markdown());
  WriteFileAtomic(out_ / "table4.csv", t4.Csv());
  WriteFileAtomic(out_ / "rounds.md",
                  "# Outer loop: triangulation + spline bundle adjustment per round\n\n"
                  "reproj before: mean reprojection error of the triangulated points with the poses and "
                  "intrinsics entering the round; after: the bundle adjuster's final mean; pose change: "
                  "RMS over images of the camera-centre / rotation change made by the round.\n\n" +
                      rounds_.Markdown() + "\n" + (converged ? "Converged" : "Stopped at the round limit") +
                      " after " + std::to_string(rounds_done) + " rounds; total change from the input poses: " +
                      Fixed(100 * total.position_m, 2) + " cm, " + Fixed(total.rotation_deg, 3) + " deg RMS.\n");
  WriteFileAtomic(out_ / "rounds.csv", rounds_.Csv());
  if (o_.ba.estimate_time_offsets) {
    // Estimated clock offset of each camera: its images are tied to the
    // spline at timestamp + offset.
    TextTable offsets;
    offsets.header = {"camera", "time offset (ms)"};
    std::string line = "estimated clock offsets (ms):";
    for (const auto& [id, cs] : state_.cameras) {
      offsets.rows.push_back({id, Fixed(1e3 * cs.time_offset_s, 3)});
      line += " " + id + " " + Fixed(1e3 * cs.time_offset_s, 2);
    }
    WriteFileAtomic(out_ / "time_offsets.csv", offsets.Csv());
    ctx_.Info(line);
  }
  // The images' correction of the LiDAR merge, per sequence (last round).
  std::string alignments_json;
  if (!alignments_.empty()) {
    TextTable table;
    table.header = {"sequence", "first timestamp", "translation (cm)", "rotation (deg)", "yaw (deg)", "scale - 1 (%)"};
    std::string line = "sequence alignments (images vs LiDAR merge):";
    for (size_t q = 0; q < alignments_.size() && q < state_.sequences.size(); ++q) {
      const Pose& g = alignments_[q];
      const double scale = q < scales_.size() ? scales_[q] : 1.0;
      // Translation at the sequence's first pose: what the correction moves it by.
      const Eigen::Vector3d p = state_.sequences[q].T_world_rig.front().t;
      const double moved_cm = 100 * (g * (scale * p) - p).norm();
      const double angle_deg = Eigen::AngleAxisd(g.q).angle() * 180 / M_PI;
      const Eigen::Vector3d x = g.q * Eigen::Vector3d::UnitX();
      const double yaw_deg = std::atan2(x.y(), x.x()) * 180 / M_PI;
      table.rows.push_back({std::to_string(q), std::to_string(state_.sequences[q].timestamps.front()),
                            Fixed(moved_cm, 2), Fixed(angle_deg, 4), Fixed(yaw_deg, 4), Fixed(100 * (scale - 1), 4)});
      line += " " + std::to_string(q) + ": " + Fixed(moved_cm, 2) + " cm / " + Fixed(angle_deg, 3) + " deg";
      alignments_json += std::string(q ? ", " : "") + "{\"sequence\": " + std::to_string(q) +
                         ", \"translation_m\": " + FormatDouble(moved_cm / 100) +
                         ", \"rotation_deg\": " + FormatDouble(angle_deg) + ", \"scale\": " + FormatDouble(scale) + "}";
    }
    WriteFileAtomic(out_ / "alignments.csv", table.Csv());
    ctx_.Info(line);
  }
  std::ostringstream json;
  json << "{\n  \"rounds\": " << rounds_done << ",\n  \"converged\": " << (converged ? "true" : "false")
       << ",\n  \"images\": " << model.images.size() << ",\n  \"points\": " << model.points3d.size()
       << ",\n  \"mean_observations_per_image\": " << FormatDouble(model.MeanObservationsPerImage())
       << ",\n  \"final_mean_reprojection_px\": " << FormatDouble(final_reproj.mean_px)
       << ",\n  \"total_position_change_m\": " << FormatDouble(total.position_m)
       << ",\n  \"total_rotation_change_deg\": " << FormatDouble(total.rotation_deg)
       << ",\n  \"sequence_alignments\": [" << alignments_json << "]"
       << ",\n  \"seconds\": " << FormatDouble(Since(start)) << "\n}\n";
  WriteFileAtomic(out_ / "spline_ba.json", json.str());
}

void OuterLoop::WriteOutputs(const colmap::Reconstruction& model) {
  // sensors.txt with the refined intrinsics, rigs.txt with the refined rotations.
  kp::Sensors sensors;
  for (const kp::Sensor& s : map_->sensors().list()) {
    auto it = state_.cameras.find(s.id);
    sensors.Add(it == state_.cameras.end() || !s.IsCamera() ? s : kp::MakeCameraSensor(s.id, s.name, it->second.camera));
  }
  kp::Rigs rigs;
  for (const kp::Rig& rig : map_->rigs().list())
    for (kp::RigSensor rs : rig.sensors) {
      auto it = state_.cameras.find(rs.sensor_id);
      if (it != state_.cameras.end() && it->second.T_cam_rig) {
        rs.sensor_from_rig = *it->second.T_cam_rig;
        rs.raw_rotation.reset();
      }
      rigs.Add(rig.id, rs);
    }
  // Refined camera poses + the spline-evaluated platform poses.
  kp::Trajectories trajectories;
  for (size_t q = 0; q < state_.sequences.size(); ++q)
    for (size_t i = 0; i < state_.sequences[q].timestamps.size(); ++i)
      trajectories.Set(state_.sequences[q].timestamps[i], o_.rig, fitted_[q][i].Inverse());
  for (const auto& [name, is] : state_.images) trajectories.Set(is.timestamp, is.device, is.T_cam_world);
  fs::create_directories(out_ / "sensors");
  kp::WriteSensors(out_ / kp::layout::kSensors, sensors);
  if (!rigs.empty()) kp::WriteRigs(out_ / kp::layout::kRigs, rigs);
  kp::WriteTrajectories(out_ / kp::layout::kTrajectories, trajectories);
  std::vector<kp::DataRecord> records;
  for (const auto& r : map_->ReadDataRecords(kp::kSensorCamera))
    if (state_.images.count(r.path)) records.push_back(r);
  kp::WriteRecords(out_ / kp::layout::RecordsFile(kp::kSensorCamera), kp::RecordKind::kCamera, records);
  if (fs::is_directory(map_->root() / kp::layout::kRecordsData)) LinkRecordData(*map_, records, out_);
  // The SfM model: COLMAP (binary) and kapture reconstruction.
  colmap::WriteModelBinary(model, out_ / "model");
  colmap::WriteKapturePoints(model, type_, out_);
  const fs::path kpts = fs::path(kp::layout::FeatureRoot(kp::FeatureKind::kKeypoints)) / type_;
  LinkTree(features_->root() / kpts, out_ / kpts);
}

}  // namespace locforge::sfm_gt

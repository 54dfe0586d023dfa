#include "locforge/colmap/kapture_database.h"

#include <set>
#include <sstream>

#include "locforge/fs.h"
#include "locforge/kapture/io.h"
#include "locforge/params.h"

namespace locforge::colmap {

std::string KeypointsType(const kapture::Kapture& features, const std::string& wanted) {
  if (!wanted.empty()) return wanted;
  const auto sets = features.FeatureSets(kapture::FeatureKind::kKeypoints);
  if (sets.size() != 1)
    throw InputError(features.root().string(), 0, "keypoints_type",
                     std::to_string(sets.size()) + " keypoints types found; name one");
  return sets.front().type;
}

DbImages AddImages(const kapture::Kapture& dataset, const kapture::Kapture& features,
                   const std::string& keypoints_type, DatabaseWriter* writer) {
  DbImages out;
  std::vector<kapture::DataRecord> records = dataset.ReadDataRecords(kapture::kSensorCamera);
  std::sort(records.begin(), records.end(),
            [](const auto& a, const auto& b) { return a.path < b.path; });
  for (const auto& r : records) {
    if (out.camera_of.count(r.device_id)) continue;
    const kapture::Sensor* sensor = dataset.sensors().Find(r.device_id);
    if (!sensor || !sensor->camera || sensor->camera->model == CameraModelId::kUnknown)
      throw InputError("sensors/sensors.txt", 0, r.device_id,
                       "camera with a COLMAP model needed for records_camera device");
    DbCamera camera;
    camera.camera = *sensor->camera;
    camera.prior_focal_length = true;
    out.camera_of[r.device_id] = 0;
    out.camera_of[r.device_id] = writer->WriteCamera(camera, false);
  }
  for (const auto& r : records) {
    if (out.id_of.count(r.path))
      throw InputError("sensors/records_camera.txt", 0, "image_path",
                       "image '" + r.path + "' recorded twice");
    DbImage image;
    image.name = r.path;
    image.camera_id = out.camera_of.at(r.device_id);
    const ImageId id = writer->WriteImage(image, false);
    out.id_of[r.path] = id;
    const kapture::FeatureArray kpts = features.ReadKeypoints(keypoints_type, r.path);
    if (kpts.dsize < 2)
      throw InputError(features.FeatureFile(kapture::FeatureKind::kKeypoints, keypoints_type, r.path).string(),
                       0, "dsize", "keypoints need x, y");
    KeypointsBlob blob;
    blob.rows = static_cast<uint32_t>(kpts.rows);
    blob.cols = 2;
    blob.data.reserve(2 * kpts.rows);
    for (int64_t i = 0; i < kpts.rows; ++i) {
      blob.data.push_back(static_cast<float>(kpts.At(i, 0)));
      blob.data.push_back(static_cast<float>(kpts.At(i, 1)));
    }
    writer->WriteKeypoints(id, blob);
    out.num_keypoints[id] = kpts.rows;
  }
  return out;
}

int64_t AddMatches(const kapture::Kapture& matches, const std::string& keypoints_type,
                   const std::map<std::string, ImageId>& ids,
                   const std::map<std::string, ImageId>& only_with,
                   DatabaseWriter* writer) {
  const auto types = matches.MatchesTypes();
  if (types.empty()) return 0;
  const std::string type =
      std::find(types.begin(), types.end(), keypoints_type) != types.end() ? keypoints_type
                                                                           : types.front();
  int64_t pairs = 0;
  for (const auto& [a, b] : matches.MatchPairs(type)) {
    auto ia = ids.find(a), ib = ids.find(b);
    if (ia == ids.end() || ib == ids.end()) continue;
    if (!only_with.empty() && !only_with.count(a) && !only_with.count(b)) continue;
    FeatureMatches fm;
    std::set<std::pair<uint32_t, uint32_t>> seen;
    for (const auto& m : matches.ReadMatches(type, a, b)) {
      const auto pair = std::make_pair(static_cast<uint32_t>(m.index1), static_cast<uint32_t>(m.index2));
      if (seen.insert(pair).second) fm.push_back(pair);
    }
    if (fm.empty()) continue;
    writer->WriteMatches(ia->second, ib->second, fm);
    TwoViewGeometry tvg;
    tvg.config = static_cast<int>(TwoViewConfig::kUncalibrated);
    tvg.inlier_matches = fm;
    writer->WriteTwoViewGeometry(ia->second, ib->second, tvg);
    ++pairs;
  }
  return pairs;
}

void AddMapperOption(std::vector<std::string>* args, const std::string& name, double value) {
  args->push_back("--Mapper." + name);
  args->push_back(FormatDouble(value));
}

void AddFixedIntrinsics(std::vector<std::string>* args) {
  for (const char* name : {"ba_refine_focal_length", "ba_refine_principal_point",
                           "ba_refine_extra_params"})
    AddMapperOption(args, name, 0);
}

void MapperParams::AddTo(std::vector<std::string>* args) const {
  AddMapperOption(args, "min_num_matches", min_num_matches);
  AddMapperOption(args, "init_min_num_inliers", init_min_num_inliers);
  AddMapperOption(args, "abs_pose_min_num_inliers", abs_pose_min_num_inliers);
  AddMapperOption(args, "abs_pose_min_inlier_ratio", abs_pose_min_inlier_ratio);
  AddMapperOption(args, "ba_local_max_num_iterations", ba_local_max_num_iterations);
  AddMapperOption(args, "abs_pose_max_error", abs_pose_max_error);
  AddMapperOption(args, "filter_max_reproj_error", filter_max_reproj_error);
  AddMapperOption(args, "tri_ignore_two_view_tracks", ignore_two_view_tracks ? 1 : 0);
}

int WriteRegisteredQueries(const Reconstruction& model, const kapture::Kapture& query,
                           const std::vector<kapture::DataRecord>& records,
                           const std::filesystem::path& out) {
  kapture::Trajectories trajectories;
  std::ostringstream failures;
  failures << "# item, timestamp, device_id, reason\n";
  int ok = 0;
  for (const auto& r : records) {
    if (const ModelImage* image = model.FindImageByName(r.path)) {
      trajectories.Set(r.timestamp, r.device_id, image->CameraFromWorld());
      ++ok;
    } else {
      failures << r.path << ", " << r.timestamp << ", " << r.device_id
               << ", not registered by image_registrator\n";
    }
  }
  std::filesystem::create_directories(out / "sensors");
  kapture::WriteSensors(out / kapture::layout::kSensors, query.sensors());
  if (!query.rigs().empty()) kapture::WriteRigs(out / kapture::layout::kRigs, query.rigs());
  kapture::WriteTrajectories(out / kapture::layout::kTrajectories, trajectories);
  WriteFileAtomic(out / "failures.txt", failures.str());
  return ok;
}

RunOptions RunOptionsFor(RunContext& ctx, const std::string& tool, double timeout_s) {
  RunOptions o;
  o.log_file = ctx.output_dir() / ("colmap_" + tool + ".log");
  o.timeout_s = timeout_s;
  o.cancelled = [&ctx] { return ctx.cancelled(); };
  return o;
}

}  // namespace locforge::colmap

#include "kapture_merge.h"

#include <algorithm>
#include <cmath>
#include <regex>
#include <tuple>
#include <set>
#include <system_error>

#include "locforge/error.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"

namespace locforge::colmap_stages {
namespace {

namespace kp = locforge::kapture;

// Equal up to the text round trip of the files (q and -q are one rotation).
bool SamePose(const Pose& a, const Pose& b) {
  return (a.t - b.t).norm() <= 1e-9 * (1 + a.t.norm()) &&
         std::abs(std::abs(a.q.dot(b.q)) - 1) <= 1e-12;
}

}  // namespace

MergeReport MergeCameraKaptures(const std::vector<MergeSource>& sources, const fs::path& dst,
                                bool copy_records_data, const std::string& image_regex) {
  if (sources.empty()) throw InputError("kapture merge: no source folder");
  std::regex keep;
  try {
    keep = std::regex(image_regex);
  } catch (const std::regex_error& e) {
    throw ParamError("images: '" + image_regex + "' is not a regular expression: " + e.what());
  }
  const bool filtered = !image_regex.empty();
  std::set<std::pair<Timestamp, std::string>> kept_images;
  kp::Sensors sensors;
  kp::Rigs rigs;
  std::set<std::pair<std::string, std::string>> rig_entries;
  kp::Trajectories trajectories;
  std::vector<kp::DataRecord> records;
  std::set<std::string> image_paths;
  MergeReport report;
  for (const auto& source : sources) {
    kp::Kapture k(source.root);
    const std::string sensors_file = (source.root / kp::layout::kSensors).string();
    for (const auto& s : k.sensors().list()) {
      if (const kp::Sensor* seen = sensors.Find(s.id)) {
        if (seen->type != s.type || seen->params != s.params)
          throw InputError(sensors_file, 0, s.id,
                           "sensor differs from the one of the same id in an earlier source");
        continue;
      }
      sensors.Add(s);
    }
    const std::string rigs_file = (source.root / kp::layout::kRigs).string();
    for (const auto& rig : k.rigs().list())
      for (const auto& rs : rig.sensors) {
        if (!rig_entries.insert({rig.id, rs.sensor_id}).second) {
          const kp::RigSensor* seen = rigs.Find(rig.id)->Find(rs.sensor_id);
          if (!SamePose(seen->sensor_from_rig, rs.sensor_from_rig))
            throw InputError(rigs_file, 0, rig.id + "/" + rs.sensor_id,
                             "rig entry differs from an earlier source's");
          continue;
        }
        rigs.Add(rig.id, rs);
      }
    const std::string traj_file = (source.root / kp::layout::kTrajectories).string();
    for (const auto& [key, pose] : k.trajectories().poses) {
      if (const Pose* seen = trajectories.Find(key.first, key.second)) {
        if (!SamePose(*seen, pose))
          throw InputError(traj_file, 0, std::to_string(key.first) + ", " + key.second,
                           "pose differs from an earlier source's at the same timestamp and device");
        continue;
      }
      trajectories.Set(key.first, key.second, pose, k.trajectories().PartsOf(key));
    }
    const std::string records_file = kp::layout::RecordsFile(kp::kSensorCamera);
    if (!k.HasRecords(kp::kSensorCamera)) continue;
    for (kp::DataRecord r : k.ReadDataRecords(kp::kSensorCamera)) {
      const fs::path from = copy_records_data
                                ? k.ExistingRecordDataPath(r.path, (source.root / records_file).string())
                                : fs::path();
      if (!source.prefix.empty()) r.path = source.prefix + "/" + r.path;
      if (filtered && !std::regex_match(r.path, keep)) continue;
      kept_images.insert({r.timestamp, r.device_id});
      if (!image_paths.insert(r.path).second)
        throw InputError((source.root / records_file).string(), 0, "image_path",
                         "'" + r.path + "' already comes from an earlier source");
      if (copy_records_data) {
        LinkOrCopyFile(from, SafeJoin(dst / kp::layout::kRecordsData, r.path, records_file));
        ++report.data_files;
      }
      records.push_back(std::move(r));
    }
  }
  kp::WriteSensors(dst / kp::layout::kSensors, sensors);
  if (!rigs.empty()) kp::WriteRigs(dst / kp::layout::kRigs, rigs);
  if (filtered) {
    kp::Trajectories kept;
    for (const auto& [key, pose] : trajectories.poses)
      if (kept_images.count(key)) kept.Set(key.first, key.second, pose, trajectories.PartsOf(key));
    trajectories = std::move(kept);
  }
  if (!trajectories.empty()) kp::WriteTrajectories(dst / kp::layout::kTrajectories, trajectories);
  std::stable_sort(records.begin(), records.end(), [](const auto& a, const auto& b) {
    return std::tie(a.timestamp, a.device_id) < std::tie(b.timestamp, b.device_id);
  });
  kp::WriteRecords(dst / kp::layout::RecordsFile(kp::kSensorCamera), kp::RecordKind::kCamera,
                   records);
  report.sensors = static_cast<int64_t>(sensors.size());
  report.poses = static_cast<int64_t>(trajectories.size());
  report.images = static_cast<int64_t>(records.size());
  return report;
}

}  // namespace locforge::colmap_stages

#include "kapture_merge.h"

#include <algorithm>
#include <cmath>
#include <map>
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

// One merge: the union of the sources' sensors, rig entries, poses and image
// records (an id seen twice must agree), then the selection of images.
struct Merger {
  Merger(const fs::path& dst, bool copy_records_data, const ImageSelection& select)
      : dst(dst), copy_records_data(copy_records_data), select(select) {}

  const fs::path& dst;
  const bool copy_records_data;
  const ImageSelection& select;
  std::regex keep;
  kp::Sensors sensors;
  kp::Rigs rigs;
  std::set<std::pair<std::string, std::string>> rig_entries;
  kp::Trajectories trajectories;
  std::vector<kp::DataRecord> records;
  std::vector<fs::path> record_files;  // records[i]'s image file (copy_records_data)
  std::set<std::string> image_paths;
  std::set<std::pair<Timestamp, std::string>> kept_images;
  MergeReport report;

  void AddSensors(kp::Kapture& k, const MergeSource& source) {
    const std::string sensors_file = (source.root / kp::layout::kSensors).string();
    for (const auto& s : k.sensors().list()) {
      if (const kp::Sensor* seen = sensors.Find(s.id)) {
        if (seen->type != s.type || seen->params != s.params)
          throw InputError(sensors_file, 0, s.id, "sensor differs from the one of the same id in an earlier source");
        continue;
      }
      sensors.Add(s);
    }
  }

  void AddRigs(kp::Kapture& k, const MergeSource& source) {
    const std::string rigs_file = (source.root / kp::layout::kRigs).string();
    for (const auto& rig : k.rigs().list())
      for (const auto& rs : rig.sensors) {
        if (!rig_entries.insert({rig.id, rs.sensor_id}).second) {
          const kp::RigSensor* seen = rigs.Find(rig.id)->Find(rs.sensor_id);
          if (!SamePose(seen->sensor_from_rig, rs.sensor_from_rig))
            throw InputError(rigs_file, 0, rig.id + "/" + rs.sensor_id, "rig entry differs from an earlier source's");
          continue;
        }
        rigs.Add(rig.id, rs);
      }
  }

  void AddPoses(kp::Kapture& k, const MergeSource& source) {
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
  }

  // The source's image records (under its prefix) that match the regex.
  void AddImages(kp::Kapture& k, const MergeSource& source) {
    const std::string records_file = kp::layout::RecordsFile(kp::kSensorCamera);
    if (!k.HasRecords(kp::kSensorCamera)) return;
    for (kp::DataRecord r : k.ReadDataRecords(kp::kSensorCamera)) {
      const fs::path from =
          copy_records_data ? k.ExistingRecordDataPath(r.path, (source.root / records_file).string()) : fs::path();
      if (!source.prefix.empty()) r.path = source.prefix + "/" + r.path;
      if (!select.regex.empty() && !std::regex_match(r.path, keep)) continue;
      if (!image_paths.insert(r.path).second)
        throw InputError((source.root / records_file).string(), 0, "image_path",
                         "'" + r.path + "' already comes from an earlier source");
      records.push_back(std::move(r));
      record_files.push_back(from);
    }
  }

  // Every sample_every-th image of each camera in time order (or the rest),
  // its file linked or copied when asked.
  void Sample() {
    std::vector<size_t> order(records.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
      return std::tie(records[a].timestamp, records[a].device_id) <
             std::tie(records[b].timestamp, records[b].device_id);
    });
    std::map<std::string, int64_t> seen_of_camera;  // images of each camera so far, in time order
    std::vector<kp::DataRecord> kept_records;
    for (size_t i : order) {
      kp::DataRecord& r = records[i];
      const bool first_of_n = seen_of_camera[r.device_id]++ % select.sample_every == 0;
      if (select.sample_every > 1 && first_of_n == select.sample_rest) continue;
      kept_images.insert({r.timestamp, r.device_id});
      if (copy_records_data) {
        LinkOrCopyFile(record_files[i], SafeJoin(dst / kp::layout::kRecordsData, r.path,
                                                 kp::layout::RecordsFile(kp::kSensorCamera)));
        ++report.data_files;
      }
      kept_records.push_back(std::move(r));
    }
    records = std::move(kept_records);
  }

  // The merged kapture; with a selection, only the kept images' poses.
  void Write(bool filtered) {
    kp::WriteSensors(dst / kp::layout::kSensors, sensors);
    if (!rigs.empty()) kp::WriteRigs(dst / kp::layout::kRigs, rigs);
    if (filtered) {
      kp::Trajectories kept;
      for (const auto& [key, pose] : trajectories.poses)
        if (kept_images.count(key)) kept.Set(key.first, key.second, pose, trajectories.PartsOf(key));
      trajectories = std::move(kept);
    }
    if (!trajectories.empty()) kp::WriteTrajectories(dst / kp::layout::kTrajectories, trajectories);
    kp::WriteRecords(dst / kp::layout::RecordsFile(kp::kSensorCamera), kp::RecordKind::kCamera, records);
    report.sensors = static_cast<int64_t>(sensors.size());
    report.poses = static_cast<int64_t>(trajectories.size());
    report.images = static_cast<int64_t>(records.size());
  }
};

}  // namespace

MergeReport MergeCameraKaptures(const std::vector<MergeSource>& sources, const fs::path& dst,
                                bool copy_records_data, const ImageSelection& select) {
  if (sources.empty()) throw InputError("kapture merge: no source folder");
  if (select.sample_every < 1)
    throw ParamError("sample_every: " + std::to_string(select.sample_every) + " is not >= 1");
  Merger m(dst, copy_records_data, select);
  try {
    m.keep = std::regex(select.regex);
  } catch (const std::regex_error& e) {
    throw ParamError("images: '" + select.regex + "' is not a regular expression: " + e.what());
  }
  for (const auto& source : sources) {
    kp::Kapture k(source.root);
    m.AddSensors(k, source);
    m.AddRigs(k, source);
    m.AddPoses(k, source);
    m.AddImages(k, source);
  }
  m.Sample();
  m.Write(!select.regex.empty() || select.sample_every > 1);
  return m.report;
}

}  // namespace locforge::colmap_stages

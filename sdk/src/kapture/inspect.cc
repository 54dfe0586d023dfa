// Inspecting a kapture dataset: InspectKapture, FormatSummary,
// FindDamagedImages (kapture.h).
#include "locforge/kapture/kapture.h"

#include <algorithm>
#include <map>
#include <set>

#include "files.h"
#include "locforge/error.h"
#include "locforge/image_check.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/rigs.h"

namespace locforge::kapture {

using namespace files;  // NOLINT: the library's own helpers

// ------------------------------------------------------------- inspection

namespace {

class ProblemList {
 public:
  explicit ProblemList(std::vector<std::string>* out) : out_(out) {}
  void Add(const std::string& category, const std::string& text) {
    if (++counts_[category] <= kPerCategory) out_->push_back(text);
  }
  void Close() {
    for (const auto& [category, n] : counts_)
      if (n > kPerCategory)
        out_->push_back("... " + std::to_string(n - kPerCategory) + " more " + category);
  }

 private:
  static constexpr int64_t kPerCategory = 10;
  std::vector<std::string>* out_;
  std::map<std::string, int64_t> counts_;
};

// One inspection: the summary and its problems, part by part of the kapture.
struct Inspector {
  explicit Inspector(const fs::path& root) : k(root), problems(&s.problems) { s.root = root; }

  Kapture k;
  KaptureSummary s;
  ProblemList problems;
  std::vector<FeatureSet> image_features;  // parallel to s.features

  void SensorsAndRigs() {
    const Sensors& sensors = k.sensors();
    for (const Sensor& sensor : sensors.list()) ++s.sensors_by_type[sensor.type];
    const Rigs& rigs = k.rigs();
    s.rigs = static_cast<int64_t>(rigs.size());
    s.rig_sensor_entries = static_cast<int64_t>(rigs.NumSensorEntries());
    for (const Rig& rig : rigs.list())
      for (const RigSensor& rs : rig.sensors)
        if (!sensors.Contains(rs.sensor_id))
          problems.Add("unknown rig sensors", std::string(layout::kRigs) + ": rig '" + rig.id + "' lists sensor '" +
                                                  rs.sensor_id + "' absent from sensors.txt");
  }

  void TrajectoryPoses() {
    const kapture::Trajectories& traj = k.trajectories();
    s.trajectory_poses = static_cast<int64_t>(traj.size());
    std::set<std::string> traj_devices;
    for (const auto& [key, pose] : traj.poses) {
      if (traj_devices.insert(key.second).second && !k.sensors().Contains(key.second) && !k.rigs().Find(key.second))
        problems.Add("unknown trajectory devices", std::string(layout::kTrajectories) + ": device '" + key.second +
                                                       "' is neither a sensor nor a rig");
    }
    s.trajectory_devices = static_cast<int64_t>(traj_devices.size());
    if (!traj.empty()) {
      s.trajectory_first = traj.poses.begin()->first.first;
      s.trajectory_last = traj.poses.rbegin()->first.first;
    }
  }

  void FeatureFiles() {
    for (FeatureKind kind : kAllKinds)
      for (const FeatureSet& set : k.FeatureSets(kind)) {
        FeatureSummary f;
        f.kind = kind;
        f.type = set.type;
        f.info = set.info;
        f.files = static_cast<int64_t>(k.FeatureImages(kind, set.type).size());
        s.features.push_back(f);
        image_features.push_back(set);
      }
  }

  // One record of a records file counted (devices: those seen in it so far).
  void Account(RecordsSummary& rs, std::set<std::string>& devices, const std::string& file, Timestamp t,
               const std::string& device) {
    if (rs.count == 0 || t < rs.first) rs.first = t;
    if (rs.count == 0 || t > rs.last) rs.last = t;
    ++rs.count;
    if (devices.insert(device).second && !k.sensors().Contains(device)) {
      problems.Add("unknown record devices", file + ": device '" + device + "' is not in sensors.txt");
    }
    if (!k.sensors().Contains(device)) ++rs.unknown_devices;
  }

  // An image record: every feature set should have a file for it.
  void CheckImageFeatures(const DataRecord& r) {
    for (size_t i = 0; i < image_features.size(); ++i) {
      const FeatureSet& set = image_features[i];
      if (!SetHasImage(set, r.path)) {
        ++s.features[i].camera_records_without_file;
        problems.Add("missing feature files", std::string(FeatureKindFolder(set.kind)) + "/" + set.type + ": no " +
                                                  FeatureKindExtension(set.kind) + " file for image " + r.path);
      }
    }
  }

  // Records with a data file: each file must exist.
  void DataRecords(const std::string& type, RecordsSummary& rs, std::set<std::string>& devices) {
    const fs::path data_root = s.root / layout::kRecordsData;
    const std::string file = layout::RecordsFile(type);
    auto reader = k.StreamRecords<DataRecord>(type);
    DataRecord r;
    while (reader.Next(&r)) {
      Account(rs, devices, file, r.timestamp, r.device_id);
      if (!IsFile(data_root / r.path)) {
        ++rs.missing_files;
        problems.Add("missing record files",
                     file + ": missing file " + std::string(layout::kRecordsData) + "/" + r.path);
      }
      if (RecordKindOf(type) == RecordKind::kCamera) CheckImageFeatures(r);
    }
  }

  // Other records: typed parsing validates every line; only the head is summarised.
  void TypedRecords(const std::string& type, RecordsSummary& rs, std::set<std::string>& devices) {
    const std::string file = layout::RecordsFile(type);
    auto run = [&](auto reader, auto record) {
      while (reader.Next(&record)) Account(rs, devices, file, record.timestamp, record.device_id);
    };
    switch (RecordKindOf(type)) {
      case RecordKind::kGnss: run(k.StreamRecords<GnssRecord>(type), GnssRecord()); break;
      case RecordKind::kWifi: run(k.StreamRecords<WifiRecord>(type), WifiRecord()); break;
      case RecordKind::kBluetooth: run(k.StreamRecords<BluetoothRecord>(type), BluetoothRecord()); break;
      case RecordKind::kAccelerometer:
      case RecordKind::kGyroscope:
      case RecordKind::kMagnetic: run(k.StreamRecords<Vector3Record>(type), Vector3Record()); break;
      default: run(k.StreamRecords<GenericRecord>(type), GenericRecord()); break;
    }
  }

  void Records() {
    for (const std::string& type : k.RecordTypes()) {
      RecordsSummary rs;
      rs.sensor_type = type;
      std::set<std::string> devices;
      if (IsDataRecordType(type))
        DataRecords(type, rs, devices);
      else
        TypedRecords(type, rs, devices);
      rs.devices = static_cast<int64_t>(devices.size());
      s.records.push_back(rs);
    }
  }

  void ReconstructionFiles() {
    for (const std::string& type : k.MatchesTypes())
      s.match_pairs[type] = static_cast<int64_t>(k.MatchPairs(type).size());
    s.points3d = static_cast<int64_t>(k.points3d().size());
    for (const ObservationsEntry& e : k.observations()) {
      ++s.observation_entries;
      s.observations += static_cast<int64_t>(e.features.size());
      if (e.point3d_id < 0 || e.point3d_id >= s.points3d)
        problems.Add("observations of unknown points", std::string(layout::kObservations) + ": point3d_id " +
                                                           std::to_string(e.point3d_id) + " is not in points3d.txt");
    }
  }
};

}  // namespace

KaptureSummary InspectKapture(const fs::path& root) {
  Inspector in(root);
  in.SensorsAndRigs();
  in.TrajectoryPoses();
  in.FeatureFiles();
  in.Records();
  in.ReconstructionFiles();
  in.problems.Close();
  return std::move(in.s);
}

std::string FormatSummary(const KaptureSummary& s) {
  std::string out = "kapture " + s.root.string() + "\n";
  auto line = [&](const std::string& text) { out += text + "\n"; };
  int64_t total_sensors = 0;
  std::string by_type;
  for (const auto& [type, n] : s.sensors_by_type) {
    total_sensors += n;
    by_type += (by_type.empty() ? "" : ", ") + type + " " + std::to_string(n);
  }
  line("sensors: " + std::to_string(total_sensors) + (by_type.empty() ? "" : " (" + by_type + ")"));
  line("rigs: " + std::to_string(s.rigs) + " (" + std::to_string(s.rig_sensor_entries) +
       " sensor entries)");
  line("trajectories: " + std::to_string(s.trajectory_poses) + " poses, " +
       std::to_string(s.trajectory_devices) + " devices" +
       (s.trajectory_poses ? ", timestamps " + std::to_string(s.trajectory_first) + " .. " +
                                 std::to_string(s.trajectory_last)
                           : ""));
  if (s.records.empty()) line("records: none");
  for (const RecordsSummary& r : s.records) {
    std::string text = "records " + r.sensor_type + ": " + std::to_string(r.count) + " from " +
                       std::to_string(r.devices) + " devices";
    if (r.count) text += ", timestamps " + std::to_string(r.first) + " .. " + std::to_string(r.last);
    if (r.missing_files) text += ", " + std::to_string(r.missing_files) + " files missing";
    if (r.unknown_devices) text += ", " + std::to_string(r.unknown_devices) + " of unknown devices";
    line(text);
  }
  if (s.features.empty()) line("features: none");
  for (const FeatureSummary& f : s.features) {
    std::string text = std::string(FeatureKindFolder(f.kind)) + " " + f.type + ": " + f.info.name +
                       ", " + f.info.dtype_name + " x " + std::to_string(f.info.dsize) + ", " +
                       std::to_string(f.files) + " files";
    if (!f.info.keypoints_type.empty()) text += ", keypoints " + f.info.keypoints_type;
    if (!f.info.metric_type.empty()) text += ", metric " + f.info.metric_type;
    if (f.camera_records_without_file)
      text += ", " + std::to_string(f.camera_records_without_file) + " camera records without one";
    line(text);
  }
  for (const auto& [type, n] : s.match_pairs)
    line("matches " + type + ": " + std::to_string(n) + " image pairs");
  line("reconstruction: " + std::to_string(s.points3d) + " points3d, " +
       std::to_string(s.observation_entries) + " observation lines (" +
       std::to_string(s.observations) + " observations)");
  if (s.problems.empty()) {
    line("problems: none");
  } else {
    line("problems: " + std::to_string(s.problems.size()) + " listed");
    for (const std::string& p : s.problems) line("  - " + p);
  }
  return out;
}

std::vector<DamagedImage> FindDamagedImages(const Kapture& kapture, int64_t* checked) {
  std::vector<DamagedImage> out;
  int64_t count = 0;
  const std::string records = layout::RecordsFile(kSensorCamera);
  std::error_code ec;
  if (fs::is_regular_file(kapture.root() / records, ec)) {
    kapture.ForEachDataRecord(kSensorCamera, [&](const DataRecord& r) {
      const fs::path file = kapture.RecordDataPath(r.path, records);
      if (!fs::is_regular_file(file, ec)) return;
      ++count;
      if (std::string why = ImageFileDamage(file); !why.empty()) out.push_back({r.path, std::move(why)});
    });
  }
  if (checked) *checked = count;
  return out;
}

}  // namespace locforge::kapture

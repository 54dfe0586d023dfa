// Exporting one complete kapture from several partial ones: ExportKapture
// (kapture.h).
#include <algorithm>
#include <functional>
#include <map>

#include "files.h"
#include "locforge/error.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"

namespace locforge::kapture {

using namespace files;  // NOLINT: the library's own helpers

namespace {

constexpr size_t kMissingListed = 100;

std::string Join(const std::vector<std::string>& values) {
  std::string out;
  for (const std::string& v : values) out += (out.empty() ? "" : ", ") + v;
  return out;
}

std::string Describe(const Sensor& s) {
  return "'" + s.name + ", " + s.type + (s.params.empty() ? "" : ", " + Join(s.params)) + "'";
}

std::string PoseText(const Pose& pose, PoseParts parts, const Eigen::Vector4d* raw) {
  return "'" + Join(FormatPoseFields(pose, parts, raw)) + "'";
}

std::string TrajectoryPoseText(const Trajectories& t, const TrajectoryKey& key) {
  const auto raw = t.raw_rotations.find(key);
  return PoseText(t.poses.at(key), t.PartsOf(key),
                  raw == t.raw_rotations.end() ? nullptr : &raw->second);
}

// Line (1-based) and byte offset of the first difference of two texts.
std::string FirstDifference(const std::string& a, const std::string& b) {
  size_t i = 0;
  while (i < a.size() && i < b.size() && a[i] == b[i]) ++i;
  const int64_t line = 1 + std::count(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(i), '\n');
  return "first difference at byte " + std::to_string(i) + " (line " + std::to_string(line) + ")";
}

class Exporter {
 public:
  Exporter(fs::path out, ExportOptions options) : out_(std::move(out)), options_(std::move(options)) {}

  void Add(const ExportSource& source);
  // Writes the merged sensors, rigs and trajectories.
  void Finish();
  ExportReport report;

 private:
  void MergeSensors(const ExportSource& source, const Kapture& k);
  void MergeRigs(const ExportSource& source, const Kapture& k);
  void MergeTrajectories(const ExportSource& source, const Kapture& k);
  int64_t AddRecords(const ExportSource& source, const Kapture& k);
  void AddRecordData(const Kapture& k, const std::string& type);
  int64_t AddFeatures(const ExportSource& source, const Kapture& k);
  int64_t AddMatches(const ExportSource& source, const Kapture& k);
  int64_t AddReconstruction(const ExportSource& source, const Kapture& k);
  // Writes `rel` (under the output) with `write` when no earlier source did
  // and returns true; else writes it aside, and the two must be equal.
  bool Place(const std::string& rel, const std::string& source,
             const std::function<void(const fs::path&)>& write);

  fs::path out_;
  ExportOptions options_;
  std::map<std::string, std::string> owner_;  // file under out_ -> source that wrote it
  Sensors sensors_;
  Rigs rigs_;
  Trajectories trajectories_;
  std::map<std::string, std::string> sensor_owner_, rig_owner_;
  std::map<TrajectoryKey, size_t> pose_owner_;  // index into names_
  std::vector<std::string> names_;              // of the sources added so far
};

bool Exporter::Place(const std::string& rel, const std::string& source,
                     const std::function<void(const fs::path&)>& write) {
  const fs::path path = out_ / rel;
  const auto it = owner_.find(rel);
  if (it == owner_.end()) {
    write(path);
    owner_[rel] = source;
    return true;
  }
  const fs::path aside = TempSibling(path);
  std::error_code ec;
  std::string mine, theirs;
  try {
    write(aside);
    mine = ReadFile(aside);
    theirs = ReadFile(path);
  } catch (...) {
    fs::remove(aside, ec);
    throw;
  }
  fs::remove(aside, ec);
  if (mine != theirs)
    throw InputError(rel, 0, "",
                     "nodes '" + it->second + "' and '" + source + "' both hold this file and disagree (" +
                         FirstDifference(theirs, mine) + "): export one of them only");
  return false;
}

void Exporter::MergeSensors(const ExportSource& source, const Kapture& k) {
  for (const Sensor& sensor : k.sensors().list()) {
    const Sensor* have = sensors_.Find(sensor.id);
    if (!have) {
      sensors_.Add(sensor);
      sensor_owner_[sensor.id] = source.name;
      continue;
    }
    if (have->type != sensor.type || have->name != sensor.name || have->params != sensor.params)
      throw InputError(source.name + "/" + layout::kSensors, 0, sensor.id,
                       "nodes '" + sensor_owner_[sensor.id] + "' and '" + source.name +
                           "' disagree on this sensor: " + Describe(*have) + " and " + Describe(sensor));
  }
}

void Exporter::MergeRigs(const ExportSource& source, const Kapture& k) {
  for (const Rig& rig : k.rigs().list()) {
    for (const RigSensor& rs : rig.sensors) {
      const Rig* have_rig = rigs_.Find(rig.id);
      const RigSensor* have = have_rig ? have_rig->Find(rs.sensor_id) : nullptr;
      const std::string key = rig.id + "/" + rs.sensor_id;
      if (!have) {
        rigs_.Add(rig.id, rs);
        rig_owner_[key] = source.name;
        continue;
      }
      const auto text = [](const RigSensor& s) {
        return PoseText(s.sensor_from_rig, s.parts, s.raw_rotation ? &*s.raw_rotation : nullptr);
      };
      if (text(*have) != text(rs))
        throw InputError(source.name + "/" + layout::kRigs, 0, key,
                         "nodes '" + rig_owner_[key] + "' and '" + source.name +
                             "' disagree on this rig sensor's pose: " + text(*have) + " and " + text(rs));
    }
  }
}

void Exporter::MergeTrajectories(const ExportSource& source, const Kapture& k) {
  const Trajectories& t = k.trajectories();
  for (const auto& [key, pose] : t.poses) {
    const auto owner = pose_owner_.find(key);
    if (owner == pose_owner_.end()) {
      trajectories_.Set(key.first, key.second, pose, t.PartsOf(key));
      if (const auto raw = t.raw_rotations.find(key); raw != t.raw_rotations.end())
        trajectories_.raw_rotations[key] = raw->second;
      pose_owner_[key] = names_.size();
      continue;
    }
    const std::string have = TrajectoryPoseText(trajectories_, key), mine = TrajectoryPoseText(t, key);
    if (have != mine)
      throw InputError(source.name + "/" + layout::kTrajectories, 0,
                       std::to_string(key.first) + ", " + key.second,
                       "nodes '" + names_[owner->second] + "' and '" + source.name +
                           "' disagree on this pose: " + have + " and " + mine +
                           " (choose one node's trajectories)");
  }
}

// Links or copies the files the records of `type` name (each once).
void Exporter::AddRecordData(const Kapture& k, const std::string& type) {
  const fs::path data = out_ / layout::kRecordsData;
  auto reader = k.StreamRecords<DataRecord>(type);
  DataRecord r;
  while (reader.Next(&r)) {
    const fs::path from = k.RecordDataPath(r.path, layout::RecordsFile(type));
    const fs::path to = JoinRecordPath(data, r.path, layout::RecordsFile(type));
    std::error_code ec;
    if (fs::exists(fs::symlink_status(to, ec))) continue;
    if (!IsFile(from)) {
      if (report.missing_data_files.size() < kMissingListed)
        report.missing_data_files.push_back(from.string());
      ++report.missing_data_count;
      continue;
    }
    if (options_.link_records_data) {
      fs::create_directories(to.parent_path());
      fs::create_symlink(fs::canonical(from), to);
    } else {
      CopyVerbatim(from, to);
    }
    ++report.data_files;
  }
}

int64_t Exporter::AddRecords(const ExportSource& source, const Kapture& k) {
  int64_t files = 0;
  for (const std::string& type : k.RecordTypes()) {
    const std::string rel = layout::RecordsFile(type);
    int64_t n = 0;
    const bool placed = Place(rel, source.name, [&](const fs::path& to) {
      n = CopyRecordsFile(k.root() / rel, to, type, source.name + "/" + rel,
                          k.root() / layout::kRecordsData);
    });
    ++files;
    if (!placed) continue;  // the same records: their files are there
    report.records[type] += n;
    if (IsDataRecordType(type)) AddRecordData(k, type);
  }
  return files;
}

int64_t Exporter::AddFeatures(const ExportSource& source, const Kapture& k) {
  int64_t files = 0;
  for (FeatureKind kind : kAllKinds) {
    for (const FeatureSet& set : k.FeatureSets(kind)) {
      const std::string dir = layout::FeatureRoot(kind) + "/" + set.type + "/";
      Place(dir + InfoFileName(kind), source.name,
            [&](const fs::path& to) { WriteFeatureInfo(to, set.info); });
      const std::string key = std::string(FeatureKindFolder(kind)) + "/" + set.type;
      for (const std::string& image : k.FeatureImages(kind, set.type)) {
        const fs::path to = FeatureFilePath(out_, kind, set.type, image);
        if (Place(Rel(to, out_), source.name, [&](const fs::path& p) {
              WriteFeatureFile(p, k.ReadFeatures(kind, set.type, image));
            }))
          ++report.feature_files[key];
        ++files;
      }
    }
  }
  return files;
}

int64_t Exporter::AddMatches(const ExportSource& source, const Kapture& k) {
  int64_t files = 0;
  for (const std::string& type : k.MatchesTypes()) {
    for (const auto& pair : k.MatchPairs(type)) {
      const std::string& image1 = pair.first;  // C++17: a lambda cannot capture a structured binding
      const std::string& image2 = pair.second;
      const std::string rel = std::string(layout::kMatches) + "/" + type + "/" +
                              layout::MatchesFile(image1, image2);
      SafeJoin(out_, rel, source.name + "/" + rel);
      if (Place(rel, source.name, [&](const fs::path& to) {
            WriteFeatureFile(to, MatchesToArray(k.ReadMatches(type, image1, image2)));
          }))
        ++report.match_pairs[type];
      ++files;
    }
  }
  return files;
}

int64_t Exporter::AddReconstruction(const ExportSource& source, const Kapture& k) {
  int64_t files = 0;
  if (IsFile(k.root() / layout::kPoints3d)) {
    if (Place(layout::kPoints3d, source.name,
              [&](const fs::path& to) { WritePoints3d(to, k.points3d()); }))
      report.points3d = static_cast<int64_t>(k.points3d().size());
    ++files;
  }
  if (IsFile(k.root() / layout::kObservations)) {
    if (Place(layout::kObservations, source.name,
              [&](const fs::path& to) { WriteObservations(to, k.observations()); }))
      report.observation_entries = static_cast<int64_t>(k.observations().size());
    ++files;
  }
  return files;
}

void Exporter::Add(const ExportSource& source) {
  if (!IsDir(source.dir)) throw InputError(source.dir.string(), 0, "", "not a folder");
  const Kapture k(source.dir);
  const bool trajectories =
      options_.trajectories_from.empty() || options_.trajectories_from == source.name;
  int64_t parts = static_cast<int64_t>(k.sensors().size() + k.rigs().size());
  parts += trajectories ? static_cast<int64_t>(k.trajectories().size()) : 0;
  MergeSensors(source, k);
  MergeRigs(source, k);
  if (trajectories) MergeTrajectories(source, k);
  names_.push_back(source.name);
  parts += AddRecords(source, k) + AddFeatures(source, k) + AddMatches(source, k) +
           AddReconstruction(source, k);
  if (parts == 0 && !IsFile(source.dir / layout::kSensors))
    throw InputError(source.dir.string(), 0, "",
                     "node '" + source.name + "' holds no kapture file (sensors/, reconstruction/)");
}

void Exporter::Finish() {
  WriteSensors(out_ / layout::kSensors, sensors_);
  if (!rigs_.empty()) WriteRigs(out_ / layout::kRigs, rigs_);
  if (!trajectories_.empty()) WriteTrajectories(out_ / layout::kTrajectories, trajectories_);
  report.sensors = static_cast<int64_t>(sensors_.size());
  report.rigs = static_cast<int64_t>(rigs_.size());
  report.trajectory_poses = static_cast<int64_t>(trajectories_.size());
}

// Puts the finished folder at `dst`: a rename, after moving an existing
// `dst` (empty, or allowed by overwrite) aside.
void Publish(const fs::path& built, const fs::path& dst) {
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(dst, ec))) {
    fs::rename(built, dst);
    return;
  }
  const fs::path old = TempSibling(dst);
  fs::rename(dst, old);
  fs::rename(built, dst);
  fs::remove_all(old, ec);
}

}  // namespace

ExportReport ExportKapture(const std::vector<ExportSource>& sources, const fs::path& dst,
                           const ExportOptions& options) {
  if (sources.empty()) throw ParamError("export: no source");
  bool trajectories_found = options.trajectories_from.empty();
  for (const ExportSource& s : sources) {
    CheckDestination(s.dir, dst, options.overwrite);
    trajectories_found |= s.name == options.trajectories_from;
  }
  if (!trajectories_found)
    throw ParamError("export: the trajectories' source '" + options.trajectories_from +
                     "' is not among the sources");
  // "OUT/" names OUT: its temporary sibling must not land inside it.
  fs::path target = fs::absolute(dst).lexically_normal();
  if (target.filename().empty()) target = target.parent_path();
  fs::create_directories(target.parent_path());
  const fs::path built = TempSibling(target);
  fs::create_directory(built);
  try {
    Exporter exporter(built, options);
    for (const ExportSource& s : sources) exporter.Add(s);
    exporter.Finish();
    Publish(built, target);
    return exporter.report;
  } catch (...) {
    std::error_code ec;
    fs::remove_all(built, ec);
    throw;
  }
}

}  // namespace locforge::kapture

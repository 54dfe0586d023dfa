#include "locforge/kapture/io.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <unordered_set>

#include "locforge/error.h"

namespace locforge::kapture {

namespace {

const char* kSensorsColumns = "sensor_id, name, sensor_type, [sensor_params]+";
const char* kRigsColumns = "rig_id, sensor_id, qw, qx, qy, qz, tx, ty, tz";
const char* kTrajectoriesColumns = "timestamp, device_id, qw, qx, qy, qz, tx, ty, tz";
const char* kPoints3dColumns = "X, Y, Z, R, G, B";
const char* kPoints3dXyzColumns = "X, Y, Z";
const char* kObservationsColumns = "point3d_id, keypoints_type, [image_path, feature_id]*";
const char* kPoseFieldNames[7] = {"qw", "qx", "qy", "qz", "tx", "ty", "tz"};

std::string Header(const std::string& columns) {
  return std::string(kKaptureVersionHeader) + "\n# " + columns + "\n";
}

// Writes a whole text file atomically from a builder callback.
template <class Fn>
void WriteText(const fs::path& path, const std::string& columns, Fn&& body) {
  AtomicFile file(path, /*binary=*/true);
  std::ostream& out = file.stream();
  out << Header(columns);
  body(out);
  file.Commit();
}

const std::string& Field(const CsvRow& row, size_t i) { return row.fields[i]; }

// The toolbox's table_to_file padding (csv.py PADDINGS): a field
// right-aligned to at least `width` characters.
std::string RightAlign(const std::string& text, size_t width) {
  return text.size() >= width ? text : std::string(width - text.size(), ' ') + text;
}
constexpr size_t kTimestampWidth = 8, kDeviceWidth = 3, kEmptyPoseFieldWidth = 4;

// "<a>, <b>, <pose fields>" padded as the toolbox's files of rigs.txt and
// trajectories.txt are: timestamp to 8, ids to 3, an empty pose field to 4
// (t265). Numbers stay unpadded: the toolbox's m1x files have ", 0.0,"
// (its newest writer would pad that to 4 as well; both read the same).
std::string PosedLine(const std::string& a, size_t a_width, const std::string& b,
                      const std::vector<std::string>& pose) {
  std::vector<std::string> f = {RightAlign(a, a_width), RightAlign(b, kDeviceWidth)};
  for (const std::string& p : pose) f.push_back(p.empty() ? RightAlign(p, kEmptyPoseFieldWidth) : p);
  return JoinCsv(f);
}

void RequireNonEmpty(const CsvRow& row, size_t i, const std::string& file,
                     const std::string& field) {
  if (row.fields[i].empty()) throw InputError(file, row.line, field, "must not be empty");
}

// Integers that Python may have written as floats ("514850400.0").
int64_t ParseIntegral(const std::string& text, const std::string& file, int64_t line,
                      const std::string& field) {
  try {
    return ParseInt64(text, file, line, field);
  } catch (const InputError&) {
    const double v = ParseDouble(text, file, line, field);
    if (!std::isfinite(v) || v != std::floor(v) || std::fabs(v) > 9.0e18)
      throw InputError(file, line, field, "expected an integer, got '" + text + "'");
    return static_cast<int64_t>(v);
  }
}

// A path relative to records_data: no absolute path, no climbing above it.
void CheckRelativePath(const std::string& path, const std::string& file, int64_t line,
                       const std::string& field) {
  if (path.empty()) throw InputError(file, line, field, "empty path");
  if (path[0] == '/' || path[0] == '\\' || (path.size() > 1 && path[1] == ':'))
    throw InputError(file, line, field,
                     "path '" + path + "' is absolute; record paths must be relative to "
                     "sensors/records_data");
  int depth = 0;
  for (const auto& part : fs::path(path)) {
    const std::string s = part.string();
    if (s == "..") {
      if (--depth < 0)
        throw InputError(file, line, field,
                         "path '" + path + "' escapes the dataset root (sensors/records_data)");
    } else if (!s.empty() && s != ".") {
      ++depth;
    }
  }
}

// The one normalisation used at read and write time, so the comparison
// in FormatPoseFields is exact.
Eigen::Quaterniond UnitQuaternion(const Eigen::Vector4d& wxyz) {
  return Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]).normalized();
}

std::string Origin(const std::string& file, int64_t line) {
  return file + ":" + std::to_string(line);
}

}  // namespace

// ------------------------------------------------------------------ poses

Pose ParsePoseFields(const CsvRow& row, size_t first, const std::string& file, PoseParts* parts,
                     std::optional<Eigen::Vector4d>* raw_rotation) {
  if (raw_rotation) raw_rotation->reset();
  double v[7];
  bool empty[7];
  for (int i = 0; i < 7; ++i) {
    const std::string& text = row.fields.at(first + i);
    empty[i] = text.empty();
    v[i] = empty[i] ? 0.0 : ParseDouble(text, file, row.line, kPoseFieldNames[i]);
  }
  const bool no_rotation = empty[0] && empty[1] && empty[2] && empty[3];
  const bool no_translation = empty[4] && empty[5] && empty[6];
  for (int i = 0; i < 7; ++i) {
    const bool group_empty = i < 4 ? no_rotation : no_translation;
    if (empty[i] && !group_empty)
      throw InputError(file, row.line, kPoseFieldNames[i],
                       "empty while other fields of the " +
                           std::string(i < 4 ? "rotation" : "translation") + " are set");
  }
  // All seven empty: the toolbox's PoseTransform(None, None), the identity.
  Pose pose;
  if (!no_rotation) {
    for (int i = 0; i < 4; ++i)
      if (!std::isfinite(v[i]))
        throw InputError(file, row.line, kPoseFieldNames[i], "is not finite");
    const double norm = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]);
    if (!(norm > 1e-6))
      throw InputError(file, row.line, "qw", "quaternion has (near) zero norm");
    pose.q = UnitQuaternion(Eigen::Vector4d(v[0], v[1], v[2], v[3]));
    if (raw_rotation && pose.q.coeffs() != Eigen::Vector4d(v[1], v[2], v[3], v[0]))
      *raw_rotation = Eigen::Vector4d(v[0], v[1], v[2], v[3]);
  }
  if (!no_translation) {
    for (int i = 4; i < 7; ++i)
      if (!std::isfinite(v[i]))
        throw InputError(file, row.line, kPoseFieldNames[i], "is not finite");
    pose.t = Eigen::Vector3d(v[4], v[5], v[6]);
  }
  *parts = static_cast<PoseParts>((no_rotation ? 0 : 1) | (no_translation ? 0 : 2));
  return pose;
}

std::vector<std::string> FormatPoseFields(const Pose& pose, PoseParts parts,
                                          const Eigen::Vector4d* raw_rotation) {
  std::vector<std::string> f(7);
  if (HasRotation(parts)) {
    // The file's own numbers while they still describe this rotation.
    const bool raw = raw_rotation && UnitQuaternion(*raw_rotation).coeffs() == pose.q.coeffs();
    const Eigen::Vector4d wxyz =
        raw ? *raw_rotation : Eigen::Vector4d(pose.q.w(), pose.q.x(), pose.q.y(), pose.q.z());
    for (int i = 0; i < 4; ++i) f[i] = FormatDouble(wxyz[i]);
  }
  if (HasTranslation(parts)) {
    for (int i = 0; i < 3; ++i) f[4 + i] = FormatDouble(pose.t[i]);
  }
  return f;
}

// ---------------------------------------------------------------- sensors

namespace {

Sensor ParseSensorRow(const CsvRow& row, const std::string& file) {
  CheckFieldCount(row, file, 3, -1, kSensorsColumns);
  RequireNonEmpty(row, 0, file, "sensor_device_id");
  RequireNonEmpty(row, 2, file, "sensor_type");
  Sensor s;
  s.id = Field(row, 0);
  s.name = Field(row, 1);
  s.type = Field(row, 2);
  s.params.assign(row.fields.begin() + 3, row.fields.end());
  if (s.type == kSensorCamera || s.type == kSensorDepth) {
    if (s.params.empty())
      throw InputError(file, row.line, "model", "a " + s.type + " needs a camera model");
    const CameraModelInfo* info = FindCameraModel(s.params[0]);
    if (!info)
      throw InputError(file, row.line, "model", "unknown camera model '" + s.params[0] + "'");
    Camera cam;
    cam.model = info->id;
    if (info->num_params < 0) {
      // UNKNOWN_CAMERA: keep what reads as numbers, the raw params stay anyway.
      try {
        if (s.params.size() > 2) {
          cam.width = static_cast<int>(ParseIntegral(s.params[1], file, row.line, "width"));
          cam.height = static_cast<int>(ParseIntegral(s.params[2], file, row.line, "height"));
          for (size_t i = 3; i < s.params.size(); ++i)
            cam.params.push_back(ParseDouble(s.params[i], file, row.line, "param"));
        }
      } catch (const InputError&) {
        cam.width = cam.height = 0;
        cam.params.clear();
      }
    } else {
      const size_t expected = 3 + static_cast<size_t>(info->num_params);
      if (s.params.size() != expected)
        throw InputError(file, row.line, "sensor_params",
                         std::string(info->name) + " needs width, height and " +
                             std::to_string(info->num_params) + " parameters (" +
                             info->param_names + "), got " + std::to_string(s.params.size() - 1) +
                             " values");
      const int64_t w = ParseIntegral(s.params[1], file, row.line, "width");
      const int64_t h = ParseIntegral(s.params[2], file, row.line, "height");
      if (w < 0 || h < 0 || w > (1 << 30) || h > (1 << 30))
        throw InputError(file, row.line, "width", "image size out of range");
      cam.width = static_cast<int>(w);
      cam.height = static_cast<int>(h);
      const char* names = info->param_names;
      std::vector<std::string> param_names = SplitCsvLine(names);
      for (size_t i = 3; i < s.params.size(); ++i)
        cam.params.push_back(ParseDouble(s.params[i], file, row.line,
                                         i - 3 < param_names.size() ? param_names[i - 3] : "param"));
      const std::string why = cam.Validate();
      if (!why.empty()) throw InputError(file, row.line, "sensor_params", why);
    }
    s.camera = cam;
  }
  return s;
}

}  // namespace

Sensors ParseSensors(std::istream& in, const std::string& display_name) {
  CsvReader csv(in, display_name);
  Sensors sensors;
  CsvRow row;
  while (csv.Next(&row)) {
    Sensor s = ParseSensorRow(row, csv.name());
    if (sensors.Contains(s.id))
      throw InputError(csv.name(), row.line, "sensor_device_id",
                       "sensor '" + s.id + "' is defined twice");
    sensors.Add(std::move(s));
  }
  return sensors;
}

Sensors ReadSensors(const fs::path& path, const std::string& display_name) {
  std::ifstream in(path, std::ios::binary);
  const std::string name = display_name.empty() ? path.string() : display_name;
  if (!in) throw InputError(name, 0, "", "cannot open file");
  return ParseSensors(in, name);
}

void WriteSensors(const fs::path& path, const Sensors& sensors) {
  WriteText(path, kSensorsColumns, [&](std::ostream& out) {
    for (const Sensor& s : sensors.list()) {
      std::vector<std::string> f = {s.id, s.name, s.type};
      f.insert(f.end(), s.params.begin(), s.params.end());
      out << JoinCsv(f) << "\n";
    }
  });
}

// ------------------------------------------------------------------- rigs

Rigs ParseRigs(std::istream& in, const std::string& display_name) {
  CsvReader csv(in, display_name);
  Rigs rigs;
  CsvRow row;
  while (csv.Next(&row)) {
    CheckFieldCount(row, csv.name(), 9, 9, kRigsColumns);
    RequireNonEmpty(row, 0, csv.name(), "rig_device_id");
    RequireNonEmpty(row, 1, csv.name(), "sensor_device_id");
    RigSensor s;
    s.sensor_id = Field(row, 1);
    s.sensor_from_rig = ParsePoseFields(row, 2, csv.name(), &s.parts, &s.raw_rotation);
    const Rig* rig = rigs.Find(Field(row, 0));
    if (rig && rig->Find(s.sensor_id))
      throw InputError(csv.name(), row.line, "sensor_device_id",
                       "sensor '" + s.sensor_id + "' is listed twice in rig '" + Field(row, 0) + "'");
    rigs.Add(Field(row, 0), std::move(s));
  }
  return rigs;
}

Rigs ReadRigs(const fs::path& path, const std::string& display_name) {
  std::ifstream in(path, std::ios::binary);
  const std::string name = display_name.empty() ? path.string() : display_name;
  if (!in) throw InputError(name, 0, "", "cannot open file");
  return ParseRigs(in, name);
}

void WriteRigs(const fs::path& path, const Rigs& rigs) {
  WriteText(path, kRigsColumns, [&](std::ostream& out) {
    for (const Rig& rig : rigs.list())
      for (const RigSensor& s : rig.sensors) {
        const auto pose = FormatPoseFields(s.sensor_from_rig, s.parts,
                                           s.raw_rotation ? &*s.raw_rotation : nullptr);
        out << PosedLine(rig.id, kDeviceWidth, s.sensor_id, pose) << "\n";
      }
  });
}

// ----------------------------------------------------------- trajectories

Trajectories ParseTrajectories(std::istream& in, const std::string& display_name) {
  CsvReader csv(in, display_name);
  Trajectories traj;
  CsvRow row;
  while (csv.Next(&row)) {
    CheckFieldCount(row, csv.name(), 9, 9, kTrajectoriesColumns);
    const Timestamp t = ParseInt64(Field(row, 0), csv.name(), row.line, "timestamp");
    RequireNonEmpty(row, 1, csv.name(), "device_id");
    PoseParts parts;
    std::optional<Eigen::Vector4d> raw;
    const Pose pose = ParsePoseFields(row, 2, csv.name(), &parts, &raw);
    if (traj.Find(t, Field(row, 1)))
      throw InputError(csv.name(), row.line, "timestamp",
                       "a second pose for (" + std::to_string(t) + ", " + Field(row, 1) + ")");
    traj.Set(t, Field(row, 1), pose, parts);
    if (raw) traj.raw_rotations.emplace(TrajectoryKey(t, Field(row, 1)), *raw);
  }
  return traj;
}

Trajectories ReadTrajectories(const fs::path& path, const std::string& display_name) {
  std::ifstream in(path, std::ios::binary);
  const std::string name = display_name.empty() ? path.string() : display_name;
  if (!in) throw InputError(name, 0, "", "cannot open file");
  return ParseTrajectories(in, name);
}

void WriteTrajectories(const fs::path& path, const Trajectories& trajectories) {
  WriteText(path, kTrajectoriesColumns, [&](std::ostream& out) {
    for (const auto& [key, pose] : trajectories.poses) {
      const auto raw = trajectories.raw_rotations.find(key);
      const auto p = FormatPoseFields(pose, trajectories.PartsOf(key),
                                      raw == trajectories.raw_rotations.end() ? nullptr : &raw->second);
      out << PosedLine(std::to_string(key.first), kTimestampWidth, key.second, p) << "\n";
    }
  });
}

// ---------------------------------------------------------------- records

namespace {
void ParseHead(const CsvRow& row, const std::string& file, Timestamp* t, std::string* device) {
  *t = ParseInt64(Field(row, 0), file, row.line, "timestamp");
  RequireNonEmpty(row, 1, file, "device_id");
  *device = Field(row, 1);
}
}  // namespace

DataRecord ParseDataRecord(const CsvRow& row, const std::string& file) {
  CheckFieldCount(row, file, 3, 3, "timestamp, device_id, path");
  DataRecord r;
  ParseHead(row, file, &r.timestamp, &r.device_id);
  r.path = Field(row, 2);
  CheckRelativePath(r.path, file, row.line, "path");
  return r;
}

GnssRecord ParseGnssRecord(const CsvRow& row, const std::string& file) {
  CheckFieldCount(row, file, 7, 7, RecordColumns(RecordKind::kGnss));
  GnssRecord r;
  ParseHead(row, file, &r.timestamp, &r.device_id);
  r.x = ParseDouble(Field(row, 2), file, row.line, "x");
  r.y = ParseDouble(Field(row, 3), file, row.line, "y");
  r.z = ParseDouble(Field(row, 4), file, row.line, "z");
  r.utc = ParseIntegral(Field(row, 5), file, row.line, "utc");
  r.dop = ParseDouble(Field(row, 6), file, row.line, "dop");
  return r;
}

WifiRecord ParseWifiRecord(const CsvRow& row, const std::string& file) {
  CheckFieldCount(row, file, 8, 8, RecordColumns(RecordKind::kWifi));
  WifiRecord r;
  ParseHead(row, file, &r.timestamp, &r.device_id);
  r.bssid = Field(row, 2);
  r.frequency = ParseIntegral(Field(row, 3), file, row.line, "frequency");
  r.rssi = ParseDouble(Field(row, 4), file, row.line, "RSSI");
  r.ssid = Field(row, 5);
  if (!Field(row, 6).empty())
    r.scan_time_start = ParseIntegral(Field(row, 6), file, row.line, "scan_time_start");
  if (!Field(row, 7).empty())
    r.scan_time_end = ParseIntegral(Field(row, 7), file, row.line, "scan_time_end");
  return r;
}

BluetoothRecord ParseBluetoothRecord(const CsvRow& row, const std::string& file) {
  CheckFieldCount(row, file, 4, 5, RecordColumns(RecordKind::kBluetooth));
  BluetoothRecord r;
  ParseHead(row, file, &r.timestamp, &r.device_id);
  r.address = Field(row, 2);
  r.rssi = ParseDouble(Field(row, 3), file, row.line, "RSSI");
  if (row.fields.size() > 4) r.name = Field(row, 4);
  return r;
}

Vector3Record ParseVector3Record(const CsvRow& row, const std::string& file) {
  CheckFieldCount(row, file, 5, 5, "timestamp, device_id, x, y, z");
  Vector3Record r;
  ParseHead(row, file, &r.timestamp, &r.device_id);
  r.x = ParseDouble(Field(row, 2), file, row.line, "x");
  r.y = ParseDouble(Field(row, 3), file, row.line, "y");
  r.z = ParseDouble(Field(row, 4), file, row.line, "z");
  return r;
}

GenericRecord ParseGenericRecord(const CsvRow& row, const std::string& file) {
  CheckFieldCount(row, file, 2, -1, "timestamp, device_id, [data]*");
  GenericRecord r;
  ParseHead(row, file, &r.timestamp, &r.device_id);
  r.values.assign(row.fields.begin() + 2, row.fields.end());
  return r;
}

namespace {

void ParseRow(const CsvRow& row, const std::string& file, DataRecord* r) { *r = ParseDataRecord(row, file); }
void ParseRow(const CsvRow& row, const std::string& file, GnssRecord* r) { *r = ParseGnssRecord(row, file); }
void ParseRow(const CsvRow& row, const std::string& file, WifiRecord* r) { *r = ParseWifiRecord(row, file); }
void ParseRow(const CsvRow& row, const std::string& file, BluetoothRecord* r) { *r = ParseBluetoothRecord(row, file); }
void ParseRow(const CsvRow& row, const std::string& file, Vector3Record* r) { *r = ParseVector3Record(row, file); }
void ParseRow(const CsvRow& row, const std::string& file, GenericRecord* r) { *r = ParseGenericRecord(row, file); }

std::vector<std::string> Format(const DataRecord& r) {
  return {std::to_string(r.timestamp), r.device_id, r.path};
}
std::vector<std::string> Format(const GnssRecord& r) {
  return {std::to_string(r.timestamp), r.device_id, FormatDouble(r.x), FormatDouble(r.y),
          FormatDouble(r.z), std::to_string(r.utc), FormatDouble(r.dop)};
}
std::vector<std::string> Format(const WifiRecord& r) {
  return {std::to_string(r.timestamp), r.device_id, r.bssid, std::to_string(r.frequency),
          FormatDouble(r.rssi), r.ssid,
          r.scan_time_start ? std::to_string(*r.scan_time_start) : "",
          r.scan_time_end ? std::to_string(*r.scan_time_end) : ""};
}
std::vector<std::string> Format(const BluetoothRecord& r) {
  return {std::to_string(r.timestamp), r.device_id, r.address, FormatDouble(r.rssi), r.name};
}
std::vector<std::string> Format(const Vector3Record& r) {
  return {std::to_string(r.timestamp), r.device_id, FormatDouble(r.x), FormatDouble(r.y),
          FormatDouble(r.z)};
}
std::vector<std::string> Format(const GenericRecord& r) {
  std::vector<std::string> f = {std::to_string(r.timestamp), r.device_id};
  f.insert(f.end(), r.values.begin(), r.values.end());
  return f;
}

}  // namespace

// Record paths are checked lexically when parsed (CheckRelativePath: no
// absolute path, no climbing out of records_data). Symbolic links under
// records_data are the dataset owner's choice (kapture's importers write
// them) and are followed; `root` only documents where paths are relative to.
template <class Record>
struct RecordsReader<Record>::PathCheck {
  fs::path root;

  void Check(const std::string& relative, const std::string& origin) {
    if (!root.empty()) JoinRecordPath(root, relative, origin);
  }
};

namespace {
template <class Record, class Check>
void CheckDataRoot(const Record&, Check*, const std::string&, int64_t) {}
template <class Check>
void CheckDataRoot(const DataRecord& r, Check* check, const std::string& file, int64_t line) {
  check->Check(r.path, Origin(file, line));
}
}  // namespace

template <class Record>
RecordsReader<Record>::RecordsReader(const fs::path& path, const std::string& display_name,
                                     fs::path records_data_root)
    : csv_(std::make_unique<CsvReader>(path, display_name)),
      paths_(std::make_unique<PathCheck>()) {
  paths_->root = std::move(records_data_root);
}

template <class Record>
RecordsReader<Record>::RecordsReader(std::istream& in, const std::string& display_name,
                                     fs::path records_data_root)
    : csv_(std::make_unique<CsvReader>(in, display_name)),
      paths_(std::make_unique<PathCheck>()) {
  paths_->root = std::move(records_data_root);
}

template <class Record>
RecordsReader<Record>::RecordsReader(RecordsReader&&) noexcept = default;
template <class Record>
RecordsReader<Record>& RecordsReader<Record>::operator=(RecordsReader&&) noexcept = default;
template <class Record>
RecordsReader<Record>::~RecordsReader() = default;

template <class Record>
bool RecordsReader<Record>::Next(Record* record) {
  CsvRow row;
  if (!csv_->Next(&row)) return false;
  ParseRow(row, csv_->name(), record);
  CheckDataRoot(*record, paths_.get(), csv_->name(), row.line);
  return true;
}

template <class Record>
const std::string& RecordsReader<Record>::name() const {
  return csv_->name();
}

template <class Record>
std::string RecordsReader<Record>::ColumnsComment() const {
  for (auto it = csv_->comments().rbegin(); it != csv_->comments().rend(); ++it)
    if (it->rfind("kapture format:", 0) != 0) return *it;
  return "";
}

template <class Record>
RecordsWriter<Record>::RecordsWriter(const fs::path& path, RecordKind kind,
                                     const std::string& columns)
    : file_(std::make_unique<AtomicFile>(path, true)) {
  std::string cols = columns;
  if (cols.empty()) cols = RecordColumns(kind);
  if (cols.empty()) cols = "timestamp, device_id, data";
  file_->stream() << Header(cols);
}

template <class Record>
RecordsWriter<Record>::~RecordsWriter() = default;

template <class Record>
void RecordsWriter<Record>::Write(const Record& record) {
  file_->stream() << JoinCsv(Format(record)) << "\n";
  ++count_;
}

template <class Record>
void RecordsWriter<Record>::Commit() {
  file_->Commit();
}

template <class Record>
std::vector<Record> ReadRecords(const fs::path& path, const std::string& display_name,
                                const fs::path& records_data_root) {
  RecordsReader<Record> reader(path, display_name, records_data_root);
  std::vector<Record> out;
  Record r;
  while (reader.Next(&r)) out.push_back(std::move(r));
  return out;
}

template <class Record>
void WriteRecords(const fs::path& path, RecordKind kind, const std::vector<Record>& records,
                  const std::string& columns) {
  RecordsWriter<Record> writer(path, kind, columns);
  for (const Record& r : records) writer.Write(r);
  writer.Commit();
}

#define LOCFORGE_KAPTURE_RECORD(R)                                                        \
  template class RecordsReader<R>;                                                        \
  template class RecordsWriter<R>;                                                        \
  template std::vector<R> ReadRecords<R>(const fs::path&, const std::string&,             \
                                         const fs::path&);                                \
  template void WriteRecords<R>(const fs::path&, RecordKind, const std::vector<R>&,       \
                                const std::string&);
LOCFORGE_KAPTURE_RECORD(DataRecord)
LOCFORGE_KAPTURE_RECORD(GnssRecord)
LOCFORGE_KAPTURE_RECORD(WifiRecord)
LOCFORGE_KAPTURE_RECORD(BluetoothRecord)
LOCFORGE_KAPTURE_RECORD(Vector3Record)
LOCFORGE_KAPTURE_RECORD(GenericRecord)
#undef LOCFORGE_KAPTURE_RECORD

// ------------------------------------------------- features configuration

namespace {
const char* FeatureColumns(FeatureKind kind) {
  switch (kind) {
    case FeatureKind::kKeypoints: return "name, dtype, dsize";
    case FeatureKind::kDescriptors: return "name, dtype, dsize, keypoints_type, metric_type";
    case FeatureKind::kGlobalFeatures: return "name, dtype, dsize, metric_type";
  }
  return "";
}
}  // namespace

FeatureInfo ParseFeatureInfo(std::istream& in, FeatureKind kind, const std::string& display_name) {
  CsvReader csv(in, display_name);
  CsvRow row;
  if (!csv.Next(&row)) throw InputError(display_name, 0, "", "no data line (expected " +
                                                                 std::string(FeatureColumns(kind)) + ")");
  // kapture 1.0 wrote "name, dtype, dsize" for every kind; 1.1 added the
  // keypoints and metric types.
  const size_t n = kind == FeatureKind::kKeypoints ? 3 : (kind == FeatureKind::kDescriptors ? 5 : 4);
  CheckFieldCount(row, csv.name(), 3, static_cast<int64_t>(n), FeatureColumns(kind));
  FeatureInfo info;
  info.kind = kind;
  info.name = Field(row, 0);
  info.dtype_name = Field(row, 1);
  if (!ParseDType(info.dtype_name, &info.dtype))
    throw InputError(csv.name(), row.line, "dtype",
                     "unknown numpy dtype '" + info.dtype_name + "'");
  info.dsize = ParseInt64(Field(row, 2), csv.name(), row.line, "dsize");
  if (info.dsize <= 0 || info.dsize > (int64_t{1} << 24))
    throw InputError(csv.name(), row.line, "dsize",
                     "must be in 1..16777216, got " + std::to_string(info.dsize));
  if (kind == FeatureKind::kDescriptors) {
    if (row.fields.size() > 3) info.keypoints_type = Field(row, 3);
    if (row.fields.size() > 4) info.metric_type = Field(row, 4);
  } else if (kind == FeatureKind::kGlobalFeatures) {
    if (row.fields.size() > 3) info.metric_type = Field(row, 3);
  }
  CsvRow extra;
  if (csv.Next(&extra))
    throw InputError(csv.name(), extra.line, "", "a second data line; this file holds one");
  return info;
}

FeatureInfo ReadFeatureInfo(const fs::path& path, FeatureKind kind, const std::string& display_name) {
  std::ifstream in(path, std::ios::binary);
  const std::string name = display_name.empty() ? path.string() : display_name;
  if (!in) throw InputError(name, 0, "", "cannot open file");
  return ParseFeatureInfo(in, kind, name);
}

void WriteFeatureInfo(const fs::path& path, const FeatureInfo& info) {
  WriteText(path, FeatureColumns(info.kind), [&](std::ostream& out) {
    std::vector<std::string> f = {info.name,
                                  info.dtype_name.empty() ? DTypeName(info.dtype) : info.dtype_name,
                                  std::to_string(info.dsize)};
    if (info.kind == FeatureKind::kDescriptors) {
      f.push_back(info.keypoints_type);
      f.push_back(info.metric_type);
    } else if (info.kind == FeatureKind::kGlobalFeatures) {
      f.push_back(info.metric_type);
    }
    // A 1.0 file without the 1.1 columns stays without them.
    while (f.size() > 3 && f.back().empty()) f.pop_back();
    out << JoinCsv(f) << "\n";
  });
}

// ----------------------------------------------------------- reconstruction

namespace {

// 3 (X, Y, Z) or 6 (X, Y, Z, R, G, B) columns, as the column comment says
// (the toolbox writes "# X, Y, Z" for points without colours), else as the
// first data line has; 0 when neither tells yet.
size_t Points3dColumns(const CsvReader& csv, const CsvRow* first_row) {
  for (const std::string& c : csv.comments())
    if (c.rfind(kPoints3dXyzColumns, 0) == 0)
      return c.find("R, G, B") != std::string::npos ? 6 : 3;
  if (first_row && first_row->fields.size() == 3) return 3;
  return 6;
}

}  // namespace

std::vector<Point3d> ParsePoints3d(std::istream& in, const std::string& display_name) {
  CsvReader csv(in, display_name);
  std::vector<Point3d> points;
  CsvRow row;
  static const char* kNames[6] = {"X", "Y", "Z", "R", "G", "B"};
  size_t columns = 0;
  while (csv.Next(&row)) {
    if (columns == 0) columns = Points3dColumns(csv, &row);
    CheckFieldCount(row, csv.name(), columns, static_cast<int64_t>(columns),
                    columns == 3 ? kPoints3dXyzColumns : kPoints3dColumns);
    double v[6] = {0, 0, 0, 0, 0, 0};
    for (size_t i = 0; i < columns; ++i)
      v[i] = ParseDouble(Field(row, i), csv.name(), row.line, kNames[i]);
    points.push_back({v[0], v[1], v[2], v[3], v[4], v[5], columns == 6});
  }
  return points;
}

std::vector<Point3d> ReadPoints3d(const fs::path& path, const std::string& display_name) {
  std::ifstream in(path, std::ios::binary);
  const std::string name = display_name.empty() ? path.string() : display_name;
  if (!in) throw InputError(name, 0, "", "cannot open file");
  return ParsePoints3d(in, name);
}

void WritePoints3d(const fs::path& path, const std::vector<Point3d>& points) {
  // The toolbox writes the colour columns unless the points have none.
  const bool colors = points.empty() || std::any_of(points.begin(), points.end(),
                                                    [](const Point3d& p) { return p.has_color; });
  WriteText(path, colors ? kPoints3dColumns : kPoints3dXyzColumns, [&](std::ostream& out) {
    for (const Point3d& p : points) {
      out << FormatDoubleSavetxt(p.x) << ',' << FormatDoubleSavetxt(p.y) << ','
          << FormatDoubleSavetxt(p.z);
      if (colors)
        out << ',' << FormatDoubleSavetxt(p.r) << ',' << FormatDoubleSavetxt(p.g) << ','
            << FormatDoubleSavetxt(p.b);
      out << '\n';
    }
  });
}

Observations ParseObservations(std::istream& in, const std::string& display_name,
                               const std::string& default_keypoints_type) {
  CsvReader csv(in, display_name);
  Observations out;
  CsvRow row;
  while (csv.Next(&row)) {
    // 1.1 has a keypoints type column; 1.0 has none. The header says which;
    // without one, the parity of the field count does.
    bool typed;
    if (!csv.version().empty()) {
      typed = csv.version() != "1.0";
    } else {
      typed = row.fields.size() % 2 == 0;
    }
    const size_t first = typed ? 2 : 1;
    if (row.fields.size() < first || (row.fields.size() - first) % 2 != 0)
      throw InputError(csv.name(), row.line, "",
                       std::string("expected ") +
                           (typed ? kObservationsColumns : "point3d_id, [image_path, feature_id]*") +
                           ", got " + std::to_string(row.fields.size()) + " fields");
    ObservationsEntry e;
    e.point3d_id = ParseInt64(Field(row, 0), csv.name(), row.line, "point3d_id");
    if (typed) {
      RequireNonEmpty(row, 1, csv.name(), "keypoints_type");
      e.keypoints_type = Field(row, 1);
    } else {
      e.keypoints_type = default_keypoints_type;
    }
    for (size_t i = first; i < row.fields.size(); i += 2) {
      RequireNonEmpty(row, i, csv.name(), "image_path");
      e.features.emplace_back(Field(row, i),
                              ParseInt64(Field(row, i + 1), csv.name(), row.line, "feature_id"));
    }
    out.push_back(std::move(e));
  }
  return out;
}

Observations ReadObservations(const fs::path& path, const std::string& display_name,
                              const std::string& default_keypoints_type) {
  std::ifstream in(path, std::ios::binary);
  const std::string name = display_name.empty() ? path.string() : display_name;
  if (!in) throw InputError(name, 0, "", "cannot open file");
  return ParseObservations(in, name, default_keypoints_type);
}

void WriteObservations(const fs::path& path, const Observations& observations) {
  for (const ObservationsEntry& e : observations)
    if (e.keypoints_type.empty())
      throw Error("observations of point " + std::to_string(e.point3d_id) +
                  " have no keypoints type; kapture 1.1 needs one");
  WriteText(path, kObservationsColumns, [&](std::ostream& out) {
    for (const ObservationsEntry& e : observations) {
      out << e.point3d_id << ", " << e.keypoints_type;
      for (const auto& [image, id] : e.features) out << ", " << image << ", " << id;
      out << "\n";
    }
  });
}

}  // namespace locforge::kapture

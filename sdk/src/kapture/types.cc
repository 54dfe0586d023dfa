#include "locforge/kapture/types.h"

#include "locforge/error.h"
#include "locforge/kapture/csv.h"

namespace locforge::kapture {

std::string Sensor::EpsgCode() const {
  if (type == kSensorGnss && !params.empty()) return params[0];
  return "";
}

Sensor MakeCameraSensor(const std::string& id, const std::string& name, const Camera& camera,
                        const std::string& type) {
  const std::string why = camera.Validate();
  if (!why.empty()) throw ParamError("camera sensor '" + id + "': " + why);
  Sensor s;
  s.id = id;
  s.name = name;
  s.type = type;
  s.params.push_back(CameraModelInfoOf(camera.model).name);
  s.params.push_back(std::to_string(camera.width));
  s.params.push_back(std::to_string(camera.height));
  for (double p : camera.params) s.params.push_back(FormatDouble(p));
  s.camera = camera;
  return s;
}

void Sensors::Add(Sensor sensor) {
  if (index_.count(sensor.id)) throw Error("sensor '" + sensor.id + "' is defined twice");
  index_.emplace(sensor.id, list_.size());
  list_.push_back(std::move(sensor));
}

const Sensor* Sensors::Find(const std::string& id) const {
  const auto it = index_.find(id);
  return it == index_.end() ? nullptr : &list_[it->second];
}

std::vector<const Sensor*> Sensors::OfType(const std::string& type) const {
  std::vector<const Sensor*> out;
  for (const Sensor& s : list_)
    if (s.type == type) out.push_back(&s);
  return out;
}

const RigSensor* Rig::Find(const std::string& sensor_id) const {
  for (const RigSensor& s : sensors)
    if (s.sensor_id == sensor_id) return &s;
  return nullptr;
}

void Rigs::Add(const std::string& rig_id, RigSensor sensor) {
  Rig* rig = nullptr;
  for (Rig& r : list_)
    if (r.id == rig_id) rig = &r;
  if (!rig) {
    list_.push_back(Rig{rig_id, {}});
    rig = &list_.back();
  }
  if (rig->Find(sensor.sensor_id))
    throw Error("rig '" + rig_id + "' lists sensor '" + sensor.sensor_id + "' twice");
  rig->sensors.push_back(std::move(sensor));
}

const Rig* Rigs::Find(const std::string& rig_id) const {
  for (const Rig& r : list_)
    if (r.id == rig_id) return &r;
  return nullptr;
}

const Rig* Rigs::RigOf(const std::string& sensor_id) const {
  for (const Rig& r : list_)
    if (r.Find(sensor_id)) return &r;
  return nullptr;
}

size_t Rigs::NumSensorEntries() const {
  size_t n = 0;
  for (const Rig& r : list_) n += r.sensors.size();
  return n;
}

void Trajectories::Set(Timestamp t, const std::string& device, const Pose& pose,
                       PoseParts parts) {
  TrajectoryKey key(t, device);
  poses[key] = pose;
  raw_rotations.erase(key);
  if (parts == PoseParts::kComplete) {
    partial.erase(key);
  } else {
    partial[key] = parts;
  }
}

const Pose* Trajectories::Find(Timestamp t, const std::string& device) const {
  const auto it = poses.find(TrajectoryKey(t, device));
  return it == poses.end() ? nullptr : &it->second;
}

PoseParts Trajectories::PartsOf(const TrajectoryKey& key) const {
  const auto it = partial.find(key);
  return it == partial.end() ? PoseParts::kComplete : it->second;
}

namespace {
struct KindName {
  RecordKind kind;
  const char* name;
  const char* columns;
};
const KindName kKinds[] = {
    {RecordKind::kCamera, "camera", "timestamp, device_id, image_path"},
    {RecordKind::kLidar, "lidar", "timestamp, device_id, point_cloud_path"},
    {RecordKind::kDepth, "depth", "timestamp, device_id, depth_map_path"},
    {RecordKind::kGnss, "gnss", "timestamp, device_id, x, y, z, utc, dop"},
    {RecordKind::kWifi, "wifi",
     "timestamp, device_id, BSSID, frequency, RSSI, SSID, scan_time_start, scan_time_end"},
    {RecordKind::kBluetooth, "bluetooth", "timestamp, device_id, address, RSSI, name"},
    {RecordKind::kAccelerometer, "accelerometer", "timestamp, device_id, x_acc, y_acc, z_acc"},
    {RecordKind::kGyroscope, "gyroscope", "timestamp, device_id, x_speed, y_speed, z_speed"},
    {RecordKind::kMagnetic, "magnetic",
     "timestamp, device_id, x_strength, y_strength, z_strength"},
};
}  // namespace

RecordKind RecordKindOf(const std::string& sensor_type) {
  for (const KindName& k : kKinds)
    if (sensor_type == k.name) return k.kind;
  return RecordKind::kGeneric;
}

const char* RecordKindName(RecordKind kind) {
  for (const KindName& k : kKinds)
    if (kind == k.kind) return k.name;
  return "";
}

const char* RecordColumns(RecordKind kind) {
  for (const KindName& k : kKinds)
    if (kind == k.kind) return k.columns;
  return "";
}

}  // namespace locforge::kapture

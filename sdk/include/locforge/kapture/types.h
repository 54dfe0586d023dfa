// kapture 1.1 data as plain structs.
//
// Conventions (checked on the shared samples, see kapture_test.cc):
//  - trajectories.txt holds T_device_world (world -> device), see pose.h.
//  - rigs.txt holds, for each sensor of a rig, T_sensor_rig (rig frame ->
//    sensor frame), so a sensor's pose is T_sensor_world = T_sensor_rig *
//    T_rig_world (the toolbox's rigs_remove; rigs.h implements it).
//  - Rotations are unit quaternions in every Pose read here (safe for
//    geometry). The toolbox writes quaternions as numpy-quaternion holds them,
//    often 1e-7 off unit length; those raw values are kept beside the poses
//    (Trajectories::raw_rotations, RigSensor::raw_rotation) and written back
//    while the pose still has the rotation they normalise to, so unchanged
//    poses round-trip exactly and changed ones are written as they are now.
//  - Timestamps are integers in the dataset's own unit.
//  - Keypoints are stored as the extractor wrote them (columns x, y, then
//    scale/orientation/affine terms), in pixels. kapture itself does not fix
//    the pixel origin: the toolbox's COLMAP import/export copies keypoint
//    coordinates unchanged, so keypoints that came from COLMAP use COLMAP's
//    convention (first pixel centre at (0.5, 0.5), camera.h), while some
//    extractors (e.g. R2D2's kapture export) put the first pixel centre at
//    (0, 0). This SDK never shifts them. (Checked on maupertuis: its SIFT
//    .kpt files and its COLMAP database hold identical keypoint values.)
#ifndef LOCFORGE_KAPTURE_TYPES_H_
#define LOCFORGE_KAPTURE_TYPES_H_

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "locforge/camera.h"
#include "locforge/pose.h"

namespace locforge::kapture {

// ---------------------------------------------------------------- sensors

// Sensor types the toolbox knows. Any other type string is kept verbatim.
inline constexpr const char* kSensorCamera = "camera";
inline constexpr const char* kSensorDepth = "depth";
inline constexpr const char* kSensorLidar = "lidar";
inline constexpr const char* kSensorGnss = "gnss";
inline constexpr const char* kSensorWifi = "wifi";
inline constexpr const char* kSensorBluetooth = "bluetooth";
inline constexpr const char* kSensorAccelerometer = "accelerometer";
inline constexpr const char* kSensorGyroscope = "gyroscope";
inline constexpr const char* kSensorMagnetic = "magnetic";

// One line of sensors.txt. `params` is the source of truth and is written
// back verbatim; `camera` is its parsed form for cameras and depth sensors.
struct Sensor {
  std::string id;
  std::string name;                 // may be empty
  std::string type;                 // "camera", "lidar", ... or anything else
  std::vector<std::string> params;  // raw, e.g. {"PINHOLE","1920","1080",...}
  // For type camera/depth: model, size and intrinsics parsed from params.
  // A model name outside camera.h's list is refused at read time; the
  // toolbox's UNKNOWN_CAMERA is kept with kUnknown and its raw numbers.
  std::optional<Camera> camera;

  bool IsCamera() const { return type == kSensorCamera; }
  // gnss: the coordinate system (e.g. "EPSG:4326"), else "".
  std::string EpsgCode() const;
};

// Builds a camera (or depth, with type = "depth") sensor whose params are
// the model name, width, height and the intrinsics formatted as the toolbox
// does. Throws ParamError when the camera does not validate.
Sensor MakeCameraSensor(const std::string& id, const std::string& name, const Camera& camera,
                        const std::string& type = kSensorCamera);

// Sensors in file order, with lookup by id.
class Sensors {
 public:
  // Throws Error when the id is already present.
  void Add(Sensor sensor);
  const Sensor* Find(const std::string& id) const;
  bool Contains(const std::string& id) const { return Find(id) != nullptr; }
  const std::vector<Sensor>& list() const { return list_; }
  size_t size() const { return list_.size(); }
  bool empty() const { return list_.empty(); }
  std::vector<const Sensor*> OfType(const std::string& type) const;

 private:
  std::vector<Sensor> list_;
  std::unordered_map<std::string, size_t> index_;
};

// ------------------------------------------------------------------ poses

// kapture lets a pose omit its rotation or its translation (empty fields):
// a rotation-only or translation-only pose, or neither (all seven fields
// empty: the toolbox's PoseTransform(None, None), e.g. the sensors of
// t265's rigs.txt). The missing part reads as identity in the Pose; these
// flags remember it so it is written back empty, as the toolbox writes it.
enum class PoseParts : uint8_t {
  kComplete = 3,
  kRotationOnly = 1,
  kTranslationOnly = 2,
  kNone = 0,
};
inline bool HasRotation(PoseParts parts) { return (static_cast<uint8_t>(parts) & 1) != 0; }
inline bool HasTranslation(PoseParts parts) { return (static_cast<uint8_t>(parts) & 2) != 0; }

// One sensor of a rig: T_sensor_rig.
struct RigSensor {
  std::string sensor_id;
  Pose sensor_from_rig;  // T_sensor_rig, unit quaternion
  PoseParts parts = PoseParts::kComplete;
  // (qw, qx, qy, qz) as in the file when not exactly unit (see the top).
  std::optional<Eigen::Vector4d> raw_rotation;
};

struct Rig {
  std::string id;
  std::vector<RigSensor> sensors;  // file order
  const RigSensor* Find(const std::string& sensor_id) const;
};

// rigs.txt, rigs in order of first appearance.
class Rigs {
 public:
  // Adds (rig_id, sensor) creating the rig if new; throws Error on a
  // duplicate (rig_id, sensor_id).
  void Add(const std::string& rig_id, RigSensor sensor);
  const Rig* Find(const std::string& rig_id) const;
  // The rig holding `sensor_id` (kapture allows one rig per sensor), or null.
  const Rig* RigOf(const std::string& sensor_id) const;
  const std::vector<Rig>& list() const { return list_; }
  size_t size() const { return list_.size(); }
  bool empty() const { return list_.empty(); }
  size_t NumSensorEntries() const;

 private:
  std::vector<Rig> list_;
};

using TrajectoryKey = std::pair<Timestamp, std::string>;  // (timestamp, device_id)

// trajectories.txt: T_device_world per (timestamp, device), sorted by
// timestamp then device id (the order the toolbox writes).
struct Trajectories {
  std::map<TrajectoryKey, Pose> poses;
  // Only the entries whose rotation or translation was empty in the file.
  std::map<TrajectoryKey, PoseParts> partial;
  // (qw, qx, qy, qz) as in the file for the entries whose quaternion was not
  // exactly unit length (see the top of this file).
  std::map<TrajectoryKey, Eigen::Vector4d> raw_rotations;

  // Sets a pose (give a unit quaternion: Pose's constructor normalises) and
  // forgets any raw rotation of that entry.
  void Set(Timestamp t, const std::string& device, const Pose& pose,
           PoseParts parts = PoseParts::kComplete);
  const Pose* Find(Timestamp t, const std::string& device) const;
  PoseParts PartsOf(const TrajectoryKey& key) const;
  size_t size() const { return poses.size(); }
  bool empty() const { return poses.empty(); }
};

// ---------------------------------------------------------------- records

// Record files the toolbox knows, by sensor type; records_<type>.txt.
// Types not listed here are read as GenericRecord.
enum class RecordKind {
  kCamera,         // records_camera.txt: image_path
  kLidar,          // records_lidar.txt: point_cloud_path
  kDepth,          // records_depth.txt: depth_map_path
  kGnss,           // records_gnss.txt: x, y, z, utc, dop
  kWifi,           // records_wifi.txt (1.1 columns)
  kBluetooth,      // records_bluetooth.txt
  kAccelerometer,  // records_accelerometer.txt: x_acc, y_acc, z_acc
  kGyroscope,      // records_gyroscope.txt: x_speed, y_speed, z_speed
  kMagnetic,       // records_magnetic.txt: x_strength, y_strength, z_strength
  kGeneric,        // records_<anything else>.txt: fields kept verbatim
};

// "camera" -> kCamera, ...; anything else -> kGeneric.
RecordKind RecordKindOf(const std::string& sensor_type);
// kCamera -> "camera", ... (kGeneric -> "").
const char* RecordKindName(RecordKind kind);
// The column comment the toolbox writes, without "# " (e.g.
// "timestamp, device_id, image_path"); "" for kGeneric.
const char* RecordColumns(RecordKind kind);

// camera, lidar, depth: a file under sensors/records_data/.
struct DataRecord {
  Timestamp timestamp = 0;
  std::string device_id;
  std::string path;  // relative to sensors/records_data, '/' separated
};

struct GnssRecord {
  Timestamp timestamp = 0;
  std::string device_id;
  double x = 0, y = 0, z = 0;  // in the sensor's EPSG coordinate system
  int64_t utc = 0;
  double dop = 0;
};

struct WifiRecord {
  Timestamp timestamp = 0;
  std::string device_id;
  std::string bssid;
  int64_t frequency = 0;  // MHz
  double rssi = 0;        // dBm
  std::string ssid;
  // Empty in the file when the scan times are unknown (the toolbox's None).
  std::optional<int64_t> scan_time_start;
  std::optional<int64_t> scan_time_end;
};

struct BluetoothRecord {
  Timestamp timestamp = 0;
  std::string device_id;
  std::string address;
  double rssi = 0;
  std::string name;  // may be empty
};

// accelerometer, gyroscope, magnetic.
struct Vector3Record {
  Timestamp timestamp = 0;
  std::string device_id;
  double x = 0, y = 0, z = 0;
};

// Any other records_<type>.txt: every field after device_id, verbatim.
struct GenericRecord {
  Timestamp timestamp = 0;
  std::string device_id;
  std::vector<std::string> values;
};

// --------------------------------------------------------- reconstruction

// points3d.txt holds "X, Y, Z, R, G, B" or, for points without colours
// (e.g. an openMVG export), "X, Y, Z" only. A file is one or the other;
// WritePoints3d writes the colour columns unless no point has a colour.
struct Point3d {
  double x = 0, y = 0, z = 0;
  double r = 0, g = 0, b = 0;  // colour 0..255, stored as float64 by the toolbox
  bool has_color = true;       // false when read from an X, Y, Z file (r, g, b are 0)
};

// One line of observations.txt (1.1): the keypoints of one type that see
// one 3D point.
struct ObservationsEntry {
  int64_t point3d_id = 0;
  std::string keypoints_type;  // "" when read from a 1.0 file (no type column)
  std::vector<std::pair<std::string, int64_t>> features;  // (image_path, feature_id)
};
using Observations = std::vector<ObservationsEntry>;

}  // namespace locforge::kapture

#endif  // LOCFORGE_KAPTURE_TYPES_H_

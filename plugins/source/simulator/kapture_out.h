// Writing the simulated recording as kapture 1.1 text files (the toolbox's
// layout: "# kapture format: 1.1", the column comment, fields joined by ", ")
// and PCD point clouds. Every file is written atomically.
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_KAPTURE_OUT_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_KAPTURE_OUT_H_

#include <cstdint>
#include <string>
#include <vector>

#include "camera_rig.h"
#include "lidar.h"
#include "locforge/fs.h"
#include "locforge/pose.h"

namespace locforge::sim {

// Shortest decimal that reads back to the same double (like Python's repr).
std::string FormatNumber(double v);
// "qw, qx, qy, qz, tx, ty, tz" of a pose.
std::string FormatPose(const Pose& pose);

// Rows of one kapture text file; written sorted by (timestamp, device) where that applies.
struct KaptureRows {
  std::vector<std::string> sensors;        // "id, name, type, params..."
  std::vector<std::string> rigs;           // "rig, sensor, pose"
  struct Timed {
    Timestamp timestamp;
    std::string device;
    std::string rest;  // everything after the device id
  };
  std::vector<Timed> trajectories, records_camera, records_lidar, records_wheel;
};

// sensors.txt lines of the rig: cameras (PINHOLE, true intrinsics), lidars,
// and the wheel encoders as a custom sensor type "wheel_encoder" with params
// (radius, axle, pulses_per_rev).
void AddRigSensors(const Rig& rig, KaptureRows* rows);
// rigs.txt: T_sensor_rig of every sensor of the platform rig "rig".
void AddRigExtrinsics(const Rig& rig, KaptureRows* rows);

// Writes a bulk data file (image, mask, point cloud) atomically: a temp
// sibling renamed over `path`, so no reader ever sees a partial file. Unlike
// WriteFileAtomic it does not fsync each of the thousands of files; the
// kapture text files, written last with WriteFileAtomic, publish the dataset.
void WriteDataFile(const fs::path& path, std::string_view bytes);

// Writes <root>/sensors/{sensors,rigs,trajectories,records_*}.txt.
void WriteKaptureText(const fs::path& root, KaptureRows rows);

// Binary PCD with fields x y z intensity ring time (time: seconds after the
// record's timestamp, float64).
std::string EncodePcd(const LidarScan& scan);
// Reads back an EncodePcd file (tests, tools); throws InputError on malformed data.
LidarScan DecodePcd(const std::string& bytes, const std::string& file_name);

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_KAPTURE_OUT_H_

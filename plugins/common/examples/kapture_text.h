// The two kapture 1.1 text files the example stages need (sensors.txt and
// records_camera.txt), read and written directly. Kept small on purpose.
#ifndef LOCFORGE_PLUGINS_COMMON_EXAMPLES_KAPTURE_TEXT_H_
#define LOCFORGE_PLUGINS_COMMON_EXAMPLES_KAPTURE_TEXT_H_

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace locforge::examples {

namespace fs = std::filesystem;

struct PinholeCamera {
  std::string id;    // sensor_device_id, e.g. "cam0"
  std::string name;
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
};

struct ImageRecord {
  int64_t timestamp = 0;
  std::string device_id;
  std::string image_path;  // relative to sensors/records_data
  int64_t line = 0;        // 1-based line in records_camera.txt (0 when written by us)
};

// <dataset>/sensors/records_camera.txt and <dataset>/sensors/records_data.
fs::path RecordsCameraFile(const fs::path& dataset);
fs::path RecordsDataDir(const fs::path& dataset);

// Writes sensors/sensors.txt and sensors/records_camera.txt atomically.
void WriteCameraDataset(const fs::path& dataset, const std::vector<PinholeCamera>& cameras,
                        const std::vector<ImageRecord>& records);

// Reads sensors/records_camera.txt; throws InputError naming file, line and
// field on malformed lines.
std::vector<ImageRecord> ReadImageRecords(const fs::path& dataset);

}  // namespace locforge::examples

#endif  // LOCFORGE_PLUGINS_COMMON_EXAMPLES_KAPTURE_TEXT_H_

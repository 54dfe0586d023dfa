#include "kapture_text.h"

#include <sstream>

#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/params.h"

namespace locforge::examples {

namespace {

constexpr const char kHeader[] = "# kapture format: 1.1\n";

std::string Trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const size_t e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

std::vector<std::string> SplitFields(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string field;
  while (std::getline(ss, field, ',')) out.push_back(Trim(field));
  return out;
}

}  // namespace

fs::path RecordsCameraFile(const fs::path& dataset) {
  return dataset / "sensors" / "records_camera.txt";
}
fs::path RecordsDataDir(const fs::path& dataset) { return dataset / "sensors" / "records_data"; }

void WriteCameraDataset(const fs::path& dataset, const std::vector<PinholeCamera>& cameras,
                        const std::vector<ImageRecord>& records) {
  std::ostringstream sensors;
  sensors << kHeader << "# sensor_device_id, name, sensor_type, [sensor_params]+\n";
  for (const auto& c : cameras)
    sensors << c.id << ", " << c.name << ", camera, PINHOLE, " << c.width << ", " << c.height
            << ", " << FormatDouble(c.fx) << ", " << FormatDouble(c.fy) << ", "
            << FormatDouble(c.cx) << ", " << FormatDouble(c.cy) << "\n";
  std::ostringstream images;
  images << kHeader << "# timestamp, device_id, image_path\n";
  for (const auto& r : records)
    images << r.timestamp << ", " << r.device_id << ", " << r.image_path << "\n";
  WriteFileAtomic(dataset / "sensors" / "sensors.txt", sensors.str());
  WriteFileAtomic(RecordsCameraFile(dataset), images.str());
}

std::vector<ImageRecord> ReadImageRecords(const fs::path& dataset) {
  const fs::path file = RecordsCameraFile(dataset);
  std::istringstream in(ReadFile(file));
  std::vector<ImageRecord> out;
  std::string line;
  int64_t number = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::string text = Trim(line);
    if (text.empty() || text[0] == '#') continue;
    const auto fields = SplitFields(text);
    if (fields.size() < 3)
      throw InputError(file.string(), number, "",
                       "expected 'timestamp, device_id, image_path', got '" + text + "'");
    ImageRecord r;
    if (!ParseInt(fields[0], &r.timestamp))
      throw InputError(file.string(), number, "timestamp", "not an integer: '" + fields[0] + "'");
    r.device_id = fields[1];
    r.image_path = fields[2];
    if (r.device_id.empty())
      throw InputError(file.string(), number, "device_id", "empty");
    if (r.image_path.empty())
      throw InputError(file.string(), number, "image_path", "empty");
    r.line = number;
    out.push_back(std::move(r));
  }
  return out;
}

}  // namespace locforge::examples

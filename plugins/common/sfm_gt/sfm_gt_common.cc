#include "sfm_gt_common.h"

#include <algorithm>
#include <cstdio>
#include <regex>
#include <sstream>

#include "locforge/error.h"

namespace locforge::sfm_gt {

int64_t LinkTree(const fs::path& src, const fs::path& dst) {
  int64_t n = 0;
  if (!fs::is_directory(src)) return 0;
  for (auto it = fs::recursive_directory_iterator(src); it != fs::recursive_directory_iterator(); ++it) {
    if (!it->is_regular_file()) continue;
    LinkOrCopyFile(it->path(), dst / it->path().lexically_relative(src));
    ++n;
  }
  return n;
}

int64_t LinkRecordData(const kp::Kapture& from, const std::vector<kp::DataRecord>& records,
                       const fs::path& to) {
  int64_t n = 0;
  for (const auto& r : records) {
    const fs::path source = from.ExistingRecordDataPath(r.path, "sensors/records_camera.txt");
    LinkOrCopyFile(source, SafeJoin(to / kp::layout::kRecordsData, r.path, "image_path"));
    ++n;
  }
  return n;
}

CameraGroups CameraGroups::Parse(const std::vector<std::string>& entries) {
  CameraGroups out;
  for (const auto& e : entries) {
    const size_t eq = e.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == e.size())
      throw ParamError("camera group '" + e + "': expected NAME=REGEX");
    try {
      std::regex check(e.substr(eq + 1));
    } catch (const std::regex_error& x) {
      throw ParamError("camera group '" + e + "': bad regex: " + x.what());
    }
    out.groups.emplace_back(e.substr(0, eq), e.substr(eq + 1));
  }
  return out;
}

std::string CameraGroups::Of(const std::string& sensor_id) const {
  for (const auto& [name, re] : groups)
    if (std::regex_match(sensor_id, std::regex(re))) return name;
  return "other";
}

std::vector<RigSequence> SplitRigSequences(const kp::Trajectories& trajectories,
                                           const std::string& rig_id, Timestamp max_gap) {
  std::vector<RigSequence> out;
  for (const auto& [key, pose] : trajectories.poses) {  // sorted by timestamp
    if (key.second != rig_id) continue;
    if (out.empty() || key.first - out.back().timestamps.back() > max_gap) out.emplace_back();
    out.back().timestamps.push_back(key.first);
    out.back().T_world_rig.push_back(pose.Inverse());
  }
  return out;
}

int SequenceOf(const std::vector<RigSequence>& sequences, Timestamp t, Timestamp margin) {
  for (size_t i = 0; i < sequences.size(); ++i)
    if (t >= sequences[i].timestamps.front() - margin && t <= sequences[i].timestamps.back() + margin)
      return static_cast<int>(i);
  return -1;
}

namespace {
std::string CsvField(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}
}  // namespace

std::string TextTable::Markdown() const {
  std::ostringstream o;
  auto row = [&](const std::vector<std::string>& r) {
    o << "|";
    for (const auto& c : r) o << " " << c << " |";
    o << "\n";
  };
  row(header);
  o << "|";
  for (size_t i = 0; i < header.size(); ++i) o << (i ? "---:|" : "---|");
  o << "\n";
  for (const auto& r : rows) row(r);
  return o.str();
}

std::string TextTable::Csv() const {
  std::ostringstream o;
  auto row = [&](const std::vector<std::string>& r) {
    for (size_t i = 0; i < r.size(); ++i) o << (i ? "," : "") << CsvField(r[i]);
    o << "\n";
  };
  row(header);
  for (const auto& r : rows) row(r);
  return o.str();
}

std::string Fixed(double value, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, value);
  return buf;
}

}  // namespace locforge::sfm_gt

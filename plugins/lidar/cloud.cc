#include "cloud.h"

#include <cstring>
#include <cmath>
#include <map>
#include <tuple>
#include <sstream>
#include <unordered_map>

#include "locforge/error.h"

namespace locforge::lidar {

namespace {
struct PcdField {
  std::string name;
  int size = 4;
  char type = 'F';
  int count = 1;
  size_t offset = 0;
};

double ReadValue(const char* p, const PcdField& f) {
  if (f.type == 'F' && f.size == 4) { float v; std::memcpy(&v, p, 4); return v; }
  if (f.type == 'F' && f.size == 8) { double v; std::memcpy(&v, p, 8); return v; }
  if (f.type == 'U' && f.size == 1) return static_cast<uint8_t>(*p);
  if (f.type == 'U' && f.size == 2) { uint16_t v; std::memcpy(&v, p, 2); return v; }
  if (f.type == 'U' && f.size == 4) { uint32_t v; std::memcpy(&v, p, 4); return v; }
  if (f.type == 'I' && f.size == 4) { int32_t v; std::memcpy(&v, p, 4); return v; }
  if (f.type == 'I' && f.size == 2) { int16_t v; std::memcpy(&v, p, 2); return v; }
  if (f.type == 'I' && f.size == 1) return static_cast<int8_t>(*p);
  return 0;
}
}  // namespace

Cloud ReadPcd(const fs::path& path) {
  const std::string data = ReadFile(path);
  const std::string file = path.string();
  std::vector<PcdField> fields;
  std::vector<int> sizes, counts;
  std::vector<char> types;
  size_t points = 0, pos = 0;
  int64_t line_number = 0;
  std::string format;
  while (pos < data.size() && format.empty()) {
    const size_t end = data.find('\n', pos);
    if (end == std::string::npos) throw InputError(file, line_number + 1, "DATA", "header ends early");
    std::istringstream line(data.substr(pos, end - pos));
    pos = end + 1;
    ++line_number;
    std::string key;
    if (!(line >> key) || key[0] == '#') continue;
    if (key == "FIELDS") {
      std::string n;
      while (line >> n) fields.push_back({n});
    } else if (key == "SIZE") {
      int v; while (line >> v) sizes.push_back(v);
    } else if (key == "TYPE") {
      char v; while (line >> v) types.push_back(v);
    } else if (key == "COUNT") {
      int v; while (line >> v) counts.push_back(v);
    } else if (key == "POINTS") {
      if (!(line >> points)) throw InputError(file, line_number, "POINTS", "expected a count");
    } else if (key == "DATA") {
      line >> format;
    }
  }
  if (fields.empty() || sizes.size() != fields.size() || types.size() != fields.size())
    throw InputError(file, 0, "FIELDS", "FIELDS, SIZE and TYPE must list the same number of fields");
  if (counts.empty()) counts.assign(fields.size(), 1);
  size_t stride = 0;
  int ix = -1, iy = -1, iz = -1, it = -1;
  for (size_t i = 0; i < fields.size(); ++i) {
    fields[i].size = sizes[i];
    fields[i].type = types[i];
    fields[i].count = counts.size() > i ? counts[i] : 1;
    fields[i].offset = stride;
    stride += static_cast<size_t>(fields[i].size) * fields[i].count;
    const std::string& n = fields[i].name;
    if (n == "x") ix = i; else if (n == "y") iy = i; else if (n == "z") iz = i;
    else if (n == "time" || n == "t" || n == "timestamp") it = i;
  }
  if (ix < 0 || iy < 0 || iz < 0) throw InputError(file, 0, "FIELDS", "x, y and z are required");
  Cloud cloud;
  cloud.points.reserve(points);
  if (it >= 0) cloud.times.reserve(points);
  if (format == "binary") {
    if (data.size() - pos < points * stride)
      throw InputError(file, 0, "DATA", "binary data shorter than POINTS x point size");
    for (size_t k = 0; k < points; ++k) {
      const char* p = data.data() + pos + k * stride;
      cloud.points.emplace_back(ReadValue(p + fields[ix].offset, fields[ix]),
                                ReadValue(p + fields[iy].offset, fields[iy]),
                                ReadValue(p + fields[iz].offset, fields[iz]));
      if (it >= 0) cloud.times.push_back(ReadValue(p + fields[it].offset, fields[it]));
    }
  } else if (format == "ascii") {
    std::istringstream in(data.substr(pos));
    std::vector<double> values(fields.size());
    for (size_t k = 0; k < points; ++k) {
      for (auto& v : values)
        if (!(in >> v)) throw InputError(file, line_number + 1 + k, "DATA", "too few values");
      cloud.points.emplace_back(values[ix], values[iy], values[iz]);
      if (it >= 0) cloud.times.push_back(values[it]);
    }
  } else {
    throw InputError(file, line_number, "DATA", "unsupported format '" + format + "' (ascii or binary)");
  }
  // Drop NaN returns (organised clouds).
  size_t kept = 0;
  for (size_t k = 0; k < cloud.points.size(); ++k) {
    if (!cloud.points[k].allFinite()) continue;
    cloud.points[kept] = cloud.points[k];
    if (!cloud.times.empty()) cloud.times[kept] = cloud.times[k];
    ++kept;
  }
  cloud.points.resize(kept);
  if (!cloud.times.empty()) cloud.times.resize(kept);
  return cloud;
}

void WritePcd(const fs::path& path, const Cloud& cloud) {
  std::ostringstream o;
  o << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n"
       "TYPE F F F\nCOUNT 1 1 1\nWIDTH "
    << cloud.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << cloud.size()
    << "\nDATA binary\n";
  std::string s = o.str();
  const size_t header = s.size();
  s.resize(header + cloud.size() * 12);
  for (size_t k = 0; k < cloud.size(); ++k) std::memcpy(&s[header + 12 * k], cloud.points[k].data(), 12);
  WriteFileAtomic(path, s);
}

void WritePly(const fs::path& path, const Cloud& cloud) {
  std::ostringstream o;
  o << "ply\nformat ascii 1.0\nelement vertex " << cloud.size()
    << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  for (const auto& p : cloud.points) o << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  WriteFileAtomic(path, o.str());
}

Cloud VoxelDownsample(const Cloud& cloud, double voxel) {
  struct Acc { Eigen::Vector3d sum = Eigen::Vector3d::Zero(); int n = 0; };
  std::map<std::tuple<int, int, int>, Acc> grid;  // ordered: deterministic output
  const double inv = 1.0 / voxel;
  for (const auto& p : cloud.points) {
    auto& a = grid[{static_cast<int>(std::floor(p.x() * inv)), static_cast<int>(std::floor(p.y() * inv)),
                    static_cast<int>(std::floor(p.z() * inv))}];
    a.sum += p.cast<double>();
    ++a.n;
  }
  Cloud out;
  out.points.reserve(grid.size());
  for (const auto& [key, a] : grid) out.points.push_back((a.sum / a.n).cast<float>());
  return out;
}

void Transform(const Pose& T, Cloud* cloud) {
  const Eigen::Matrix3f R = T.R().cast<float>();
  const Eigen::Vector3f t = T.t.cast<float>();
  for (auto& p : cloud->points) p = R * p + t;
}

}  // namespace locforge::lidar

// PLY and PCD readers/writers. Both formats are a text header declaring typed
// fields, then records (text lines or packed little-endian binary); one
// record decoder serves both once the header is parsed into `Field`s.
#include "locforge/pointcloud_io.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <sstream>
#include <string>

#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/params.h"

namespace locforge {

namespace fs = std::filesystem;

namespace {

// One declared field: numeric kind ('i' signed, 'u' unsigned, 'f' float),
// byte size of one element, element count, byte offset in a binary record.
struct Field {
  std::string name;
  char kind = 'f';
  int size = 4;
  int count = 1;
  size_t offset = 0;
};

double DecodeBinary(const char* p, char kind, int size) {
  switch (kind) {
    case 'f':
      if (size == 4) { float v; std::memcpy(&v, p, 4); return v; }
      { double v; std::memcpy(&v, p, 8); return v; }
    case 'i':
      if (size == 1) { int8_t v; std::memcpy(&v, p, 1); return v; }
      if (size == 2) { int16_t v; std::memcpy(&v, p, 2); return v; }
      if (size == 4) { int32_t v; std::memcpy(&v, p, 4); return v; }
      { int64_t v; std::memcpy(&v, p, 8); return static_cast<double>(v); }
    default:
      if (size == 1) { uint8_t v; std::memcpy(&v, p, 1); return v; }
      if (size == 2) { uint16_t v; std::memcpy(&v, p, 2); return v; }
      if (size == 4) { uint32_t v; std::memcpy(&v, p, 4); return v; }
      { uint64_t v; std::memcpy(&v, p, 8); return static_cast<double>(v); }
  }
}

// Where each known field goes; -1 when absent.
struct Slots {
  int x = -1, y = -1, z = -1, nx = -1, ny = -1, nz = -1, time = -1, intensity = -1, ring = -1;

  static Slots Of(const std::vector<Field>& fields, const std::string& file) {
    Slots s;
    for (int i = 0; i < static_cast<int>(fields.size()); ++i) {
      const std::string& n = fields[i].name;
      if (n == "x") s.x = i;
      else if (n == "y") s.y = i;
      else if (n == "z") s.z = i;
      else if (n == "nx" || n == "normal_x") s.nx = i;
      else if (n == "ny" || n == "normal_y") s.ny = i;
      else if (n == "nz" || n == "normal_z") s.nz = i;
      else if (n == "time" || n == "timestamp" || n == "t") s.time = i;
      else if (n == "intensity" || n == "scalar_intensity") s.intensity = i;
      else if (n == "ring") s.ring = i;
    }
    if (s.x < 0 || s.y < 0 || s.z < 0)
      throw InputError(file, 0, s.x < 0 ? "x" : s.y < 0 ? "y" : "z", "position field missing");
    return s;
  }
  bool normals() const { return nx >= 0 && ny >= 0 && nz >= 0; }

  void Prepare(size_t n, PointCloud* c, PointAttributes* a) const {
    c->points.resize(n);
    if (normals()) c->normals.resize(n);
    if (time >= 0) c->times.resize(n);
    if (a) {
      *a = PointAttributes{};
      if (intensity >= 0) a->intensity.resize(n);
      if (ring >= 0) a->ring.resize(n);
    }
  }
  // `v[i]` is the first element of field i of point `k`.
  void Store(const double* v, size_t k, PointCloud* c, PointAttributes* a) const {
    c->points[k] = Eigen::Vector3d(v[x], v[y], v[z]).cast<float>();
    if (normals()) c->normals[k] = Eigen::Vector3d(v[nx], v[ny], v[nz]).cast<float>();
    if (time >= 0) c->times[k] = v[time];
    if (a && intensity >= 0) a->intensity[k] = static_cast<float>(v[intensity]);
    if (a && ring >= 0) a->ring[k] = static_cast<uint16_t>(v[ring]);
  }
};

size_t RecordSize(std::vector<Field>* fields) {
  size_t offset = 0;
  for (Field& f : *fields) {
    f.offset = offset;
    offset += static_cast<size_t>(f.size) * f.count;
  }
  return offset;
}

void DecodeBinaryRecords(const std::string& bytes, size_t data, size_t n,
                         std::vector<Field> fields, const std::string& file, PointCloud* cloud,
                         PointAttributes* attributes) {
  const size_t record = RecordSize(&fields);
  const Slots slots = Slots::Of(fields, file);
  const size_t available = bytes.size() > data ? bytes.size() - data : 0;
  if (available / std::max<size_t>(record, 1) < n)
    throw InputError(file, 0, "DATA",
                     "truncated: " + std::to_string(available / std::max<size_t>(record, 1)) +
                         " complete records of " + std::to_string(n) + " declared");
  slots.Prepare(n, cloud, attributes);
  std::vector<double> v(fields.size());
  for (size_t k = 0; k < n; ++k) {
    const char* rec = bytes.data() + data + k * record;
    for (size_t i = 0; i < fields.size(); ++i)
      v[i] = DecodeBinary(rec + fields[i].offset, fields[i].kind, fields[i].size);
    slots.Store(v.data(), k, cloud, attributes);
  }
}

// Ascii records, one per line starting at `data`; `first_line` numbers lines.
void DecodeAsciiRecords(const std::string& bytes, size_t data, size_t n,
                        const std::vector<Field>& fields, const std::string& file,
                        int64_t first_line, PointCloud* cloud, PointAttributes* attributes) {
  const Slots slots = Slots::Of(fields, file);
  slots.Prepare(n, cloud, attributes);
  std::vector<double> v(fields.size());
  size_t pos = data;
  for (size_t k = 0; k < n; ++k) {
    const int64_t line = first_line + static_cast<int64_t>(k);
    if (pos >= bytes.size())
      throw InputError(file, line, "",
                       "truncated: " + std::to_string(k) + " of " + std::to_string(n) +
                           " declared points");
    size_t end = bytes.find('\n', pos);
    const bool last = end == std::string::npos;
    if (last) end = bytes.size();
    const char* p = bytes.data() + pos;
    const char* stop = bytes.data() + end;
    for (size_t i = 0; i < fields.size(); ++i) {
      for (int e = 0; e < fields[i].count; ++e) {
        while (p < stop && std::isspace(static_cast<unsigned char>(*p))) ++p;
        char* after = nullptr;
        const double value = std::strtod(p, &after);
        if (after == p || after > stop)
          throw InputError(file, line, fields[i].name,
                           last && p >= stop ? "truncated: the file ends inside point " +
                                                   std::to_string(k + 1) + " of " +
                                                   std::to_string(n)
                                             : "expected a number");
        if (e == 0) v[i] = value;
        p = after;
      }
    }
    slots.Store(v.data(), k, cloud, attributes);
    pos = end + 1;
  }
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Splits the header (up to and including the line that `is_last` accepts)
// into lines; returns the offset of the data.
size_t HeaderLines(const std::string& bytes, const std::string& file,
                   bool (*is_last)(const std::string&), std::vector<std::string>* lines) {
  size_t pos = 0;
  while (pos < bytes.size()) {
    size_t end = bytes.find('\n', pos);
    if (end == std::string::npos) break;
    std::string line = bytes.substr(pos, end - pos);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines->push_back(line);
    pos = end + 1;
    if (is_last(line)) return pos;
    if (lines->size() > 10000) break;
  }
  throw InputError(file, static_cast<int64_t>(lines->size()), "", "header does not end");
}

bool PlyType(const std::string& t, char* kind, int* size) {
  static const struct { const char* name; char kind; int size; } kTypes[] = {
      {"char", 'i', 1},   {"int8", 'i', 1},    {"uchar", 'u', 1},   {"uint8", 'u', 1},
      {"short", 'i', 2},  {"int16", 'i', 2},   {"ushort", 'u', 2},  {"uint16", 'u', 2},
      {"int", 'i', 4},    {"int32", 'i', 4},   {"uint", 'u', 4},    {"uint32", 'u', 4},
      {"float", 'f', 4},  {"float32", 'f', 4}, {"double", 'f', 8},  {"float64", 'f', 8}};
  for (const auto& k : kTypes)
    if (t == k.name) {
      *kind = k.kind;
      *size = k.size;
      return true;
    }
  return false;
}

const char* PlyTypeName(char kind, int size) {
  if (kind == 'f') return size == 8 ? "double" : "float";
  if (kind == 'u') return size == 1 ? "uchar" : size == 2 ? "ushort" : "uint";
  return size == 1 ? "char" : size == 2 ? "short" : "int";
}

// The fields written for `cloud`, in the order of the header comment.
std::vector<Field> OutputFields(const PointCloud& cloud, const PointAttributes* a, bool pcd) {
  cloud.CheckConsistent();
  const size_t n = cloud.size();
  std::vector<Field> f = {{"x", 'f', 4}, {"y", 'f', 4}, {"z", 'f', 4}};
  if (cloud.has_normals()) {
    f.push_back({pcd ? "normal_x" : "nx", 'f', 4});
    f.push_back({pcd ? "normal_y" : "ny", 'f', 4});
    f.push_back({pcd ? "normal_z" : "nz", 'f', 4});
  }
  if (a && !a->intensity.empty()) {
    if (a->intensity.size() != n) throw Error("point cloud: intensity count differs from points");
    f.push_back({"intensity", 'f', 4});
  }
  if (a && !a->ring.empty()) {
    if (a->ring.size() != n) throw Error("point cloud: ring count differs from points");
    f.push_back({"ring", 'u', 2});
  }
  if (cloud.has_times()) f.push_back({"time", 'f', 8});
  RecordSize(&f);
  return f;
}

// What an output field holds, resolved from its name once per file (not per point).
enum class Source { kNone, kX, kY, kZ, kNx, kNy, kNz, kIntensity, kRing, kTime };

std::vector<Source> SourcesOf(const std::vector<Field>& fields) {
  std::vector<Source> out;
  for (const Field& f : fields) {
    const std::string& n = f.name;
    out.push_back(n == "x" ? Source::kX
                  : n == "y" ? Source::kY
                  : n == "z" ? Source::kZ
                  : (n == "nx" || n == "normal_x") ? Source::kNx
                  : (n == "ny" || n == "normal_y") ? Source::kNy
                  : (n == "nz" || n == "normal_z") ? Source::kNz
                  : n == "intensity" ? Source::kIntensity
                  : n == "ring" ? Source::kRing
                  : n == "time" ? Source::kTime
                                : Source::kNone);
  }
  return out;
}

// Appends point k's records (binary or ascii, fields as from OutputFields,
// `sources` = SourcesOf(fields)).
void AppendRecord(const PointCloud& c, const PointAttributes* a, const std::vector<Field>& fields,
                  const std::vector<Source>& sources, size_t k, PointCloudEncoding enc, std::string* out) {
  for (size_t i = 0; i < fields.size(); ++i) {
    const Field& f = fields[i];
    double v = 0;
    switch (sources[i]) {
      case Source::kX: v = c.points[k].x(); break;
      case Source::kY: v = c.points[k].y(); break;
      case Source::kZ: v = c.points[k].z(); break;
      case Source::kNx: v = c.normals[k].x(); break;
      case Source::kNy: v = c.normals[k].y(); break;
      case Source::kNz: v = c.normals[k].z(); break;
      case Source::kIntensity: v = a->intensity[k]; break;
      case Source::kRing: v = a->ring[k]; break;
      case Source::kTime: v = c.times[k]; break;
      case Source::kNone: break;
    }
    if (enc == PointCloudEncoding::kBinary) {
      char buf[8];
      if (f.kind == 'f' && f.size == 4) {
        const float x = static_cast<float>(v);
        std::memcpy(buf, &x, 4);
      } else if (f.kind == 'f') {
        std::memcpy(buf, &v, 8);
      } else {
        const uint16_t x = static_cast<uint16_t>(v);
        std::memcpy(buf, &x, 2);
      }
      out->append(buf, f.size);
    } else {
      if (&f != &fields.front()) out->push_back(' ');
      if (f.kind == 'f' && f.size == 4) {
        char buf[32];
        std::snprintf(buf, sizeof(buf), "%.9g", static_cast<float>(v));
        out->append(buf);
      } else if (f.kind == 'f') {
        out->append(FormatDouble(v));
      } else {
        out->append(std::to_string(static_cast<uint16_t>(v)));
      }
    }
  }
  if (enc == PointCloudEncoding::kAscii) out->push_back('\n');
}

}  // namespace

// ---- PLY ------------------------------------------------------------------

PointCloud DecodePly(const std::string& bytes, const std::string& file,
                     PointAttributes* attributes) {
  std::vector<std::string> lines;
  const size_t data =
      HeaderLines(bytes, file, [](const std::string& l) { return l == "end_header"; }, &lines);
  if (lines.empty() || lines[0] != "ply") throw InputError(file, 1, "", "not a PLY file");
  bool binary = false, seen_format = false;
  // Elements before "vertex" (rare) are skipped when binary with fixed sizes.
  struct Element {
    std::string name;
    size_t count = 0;
    std::vector<Field> fields;
  };
  std::vector<Element> elements;
  for (size_t i = 1; i < lines.size(); ++i) {
    const int64_t ln = static_cast<int64_t>(i) + 1;
    std::istringstream in(lines[i]);
    std::string word;
    in >> word;
    if (word == "format") {
      std::string fmt;
      in >> fmt;
      if (fmt == "ascii") binary = false;
      else if (fmt == "binary_little_endian") binary = true;
      else throw InputError(file, ln, "format", "unsupported PLY format '" + fmt + "'");
      seen_format = true;
    } else if (word == "element") {
      Element e;
      long long count = -1;
      in >> e.name >> count;
      if (!in || count < 0) throw InputError(file, ln, "element", "expected a name and a count");
      e.count = static_cast<size_t>(count);
      elements.push_back(e);
    } else if (word == "property") {
      if (elements.empty()) throw InputError(file, ln, "property", "property before element");
      std::string type, name;
      in >> type;
      Field f;
      if (type == "list") {
        if (elements.back().name == "vertex")
          throw InputError(file, ln, "property", "list properties of vertices are not supported");
        f.kind = 'L';  // only allowed after the vertex element
        in >> type >> type;
      } else if (!PlyType(type, &f.kind, &f.size)) {
        throw InputError(file, ln, "property", "unknown type '" + type + "'");
      }
      in >> f.name;
      elements.back().fields.push_back(f);
    }
  }
  if (!seen_format) throw InputError(file, 2, "format", "missing");
  size_t offset = data;
  int64_t line = static_cast<int64_t>(lines.size()) + 1;
  for (Element& e : elements) {
    if (e.name == "vertex") {
      PointCloud cloud;
      if (binary)
        DecodeBinaryRecords(bytes, offset, e.count, e.fields, file, &cloud, attributes);
      else
        DecodeAsciiRecords(bytes, offset, e.count, e.fields, file, line, &cloud, attributes);
      return cloud;
    }
    for (const Field& f : e.fields)
      if (f.kind == 'L')
        throw InputError(file, 0, e.name, "list element before the vertices is not supported");
    if (binary) {
      offset += RecordSize(&e.fields) * e.count;
    } else {
      for (size_t k = 0; k < e.count; ++k) {
        offset = bytes.find('\n', offset);
        if (offset == std::string::npos) throw InputError(file, line, e.name, "truncated");
        ++offset;
        ++line;
      }
    }
  }
  throw InputError(file, 0, "element vertex", "no vertex element");
}

std::string EncodePly(const PointCloud& cloud, PointCloudEncoding enc,
                      const PointAttributes* attributes) {
  const std::vector<Field> fields = OutputFields(cloud, attributes, false);
  std::string out = "ply\nformat ";
  out += enc == PointCloudEncoding::kBinary ? "binary_little_endian" : "ascii";
  out += " 1.0\ncomment locforge\nelement vertex " + std::to_string(cloud.size()) + "\n";
  for (const Field& f : fields)
    out += std::string("property ") + PlyTypeName(f.kind, f.size) + " " + f.name + "\n";
  out += "end_header\n";
  const std::vector<Source> sources = SourcesOf(fields);
  for (size_t k = 0; k < cloud.size(); ++k) AppendRecord(cloud, attributes, fields, sources, k, enc, &out);
  return out;
}

// ---- PCD ------------------------------------------------------------------

PointCloud DecodePcd(const std::string& bytes, const std::string& file,
                     PointAttributes* attributes) {
  std::vector<std::string> lines;
  const size_t data = HeaderLines(
      bytes, file, [](const std::string& l) { return l.rfind("DATA", 0) == 0; }, &lines);
  std::vector<Field> fields;
  std::vector<std::string> sizes, types, counts;
  long long points = -1, width = -1, height = 1;
  std::string encoding;
  auto rest = [](std::istringstream& in) {
    std::vector<std::string> v;
    std::string w;
    while (in >> w) v.push_back(w);
    return v;
  };
  int64_t fields_line = 0;
  for (size_t i = 0; i < lines.size(); ++i) {
    const int64_t ln = static_cast<int64_t>(i) + 1;
    if (lines[i].empty() || lines[i][0] == '#') continue;
    std::istringstream in(lines[i]);
    std::string key;
    in >> key;
    if (key == "FIELDS" || key == "COLUMNS") {
      fields_line = ln;
      for (const auto& n : rest(in)) fields.push_back({n, 'f', 4, 1, 0});
    } else if (key == "SIZE") {
      sizes = rest(in);
    } else if (key == "TYPE") {
      types = rest(in);
    } else if (key == "COUNT") {
      counts = rest(in);
    } else if (key == "WIDTH") {
      if (!(in >> width) || width < 0) throw InputError(file, ln, "WIDTH", "expected a count");
    } else if (key == "HEIGHT") {
      if (!(in >> height) || height < 0) throw InputError(file, ln, "HEIGHT", "expected a count");
    } else if (key == "POINTS") {
      if (!(in >> points) || points < 0) throw InputError(file, ln, "POINTS", "expected a count");
    } else if (key == "DATA") {
      in >> encoding;
    }
  }
  if (fields.empty()) throw InputError(file, 0, "FIELDS", "missing");
  if (sizes.size() != fields.size() || types.size() != fields.size())
    throw InputError(file, fields_line, "SIZE/TYPE", "must have one entry per field");
  if (!counts.empty() && counts.size() != fields.size())
    throw InputError(file, fields_line, "COUNT", "must have one entry per field");
  for (size_t i = 0; i < fields.size(); ++i) {
    Field& f = fields[i];
    f.size = std::atoi(sizes[i].c_str());
    f.kind = static_cast<char>(std::tolower(static_cast<unsigned char>(types[i][0])));
    f.count = counts.empty() ? 1 : std::atoi(counts[i].c_str());
    const bool ok = (f.kind == 'f' && (f.size == 4 || f.size == 8)) ||
                    ((f.kind == 'i' || f.kind == 'u') &&
                     (f.size == 1 || f.size == 2 || f.size == 4 || f.size == 8));
    if (!ok || f.count < 1 || types[i].size() != 1)
      throw InputError(file, fields_line, f.name,
                       "unsupported SIZE " + sizes[i] + " / TYPE " + types[i]);
  }
  if (points < 0) points = width * height;
  if (points < 0) throw InputError(file, 0, "POINTS", "missing");
  PointCloud cloud;
  if (encoding == "binary")
    DecodeBinaryRecords(bytes, data, static_cast<size_t>(points), fields, file, &cloud, attributes);
  else if (encoding == "ascii")
    DecodeAsciiRecords(bytes, data, static_cast<size_t>(points), fields, file,
                       static_cast<int64_t>(lines.size()) + 1, &cloud, attributes);
  else
    throw InputError(file, static_cast<int64_t>(lines.size()), "DATA",
                     "unsupported encoding '" + encoding + "' (ascii or binary)");
  return cloud;
}

std::string EncodePcd(const PointCloud& cloud, PointCloudEncoding enc,
                      const PointAttributes* attributes) {
  const std::vector<Field> fields = OutputFields(cloud, attributes, true);
  std::string names, sizes, types, counts;
  for (const Field& f : fields) {
    names += " " + f.name;
    sizes += " " + std::to_string(f.size);
    types += std::string(" ") + static_cast<char>(std::toupper(f.kind));
    counts += " 1";
  }
  const std::string n = std::to_string(cloud.size());
  std::string out = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS" + names +
                    "\nSIZE" + sizes + "\nTYPE" + types + "\nCOUNT" + counts + "\nWIDTH " + n +
                    "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + n + "\nDATA " +
                    (enc == PointCloudEncoding::kBinary ? "binary" : "ascii") + "\n";
  const std::vector<Source> sources = SourcesOf(fields);
  for (size_t k = 0; k < cloud.size(); ++k) AppendRecord(cloud, attributes, fields, sources, k, enc, &out);
  return out;
}

// ---- Files ----------------------------------------------------------------

PointCloud ReadPly(const fs::path& file, PointAttributes* attributes) {
  return DecodePly(ReadFile(file), file.string(), attributes);
}
PointCloud ReadPcd(const fs::path& file, PointAttributes* attributes) {
  return DecodePcd(ReadFile(file), file.string(), attributes);
}
void WritePly(const fs::path& file, const PointCloud& cloud, PointCloudEncoding enc,
              const PointAttributes* attributes) {
  WriteFileAtomic(file, EncodePly(cloud, enc, attributes));
}
void WritePcd(const fs::path& file, const PointCloud& cloud, PointCloudEncoding enc,
              const PointAttributes* attributes) {
  WriteFileAtomic(file, EncodePcd(cloud, enc, attributes));
}

PointCloud ReadPointCloud(const fs::path& file, PointAttributes* attributes) {
  const std::string ext = Lower(file.extension().string());
  if (ext == ".ply") return ReadPly(file, attributes);
  if (ext == ".pcd") return ReadPcd(file, attributes);
  throw InputError(file.string(), 0, "", "unknown point cloud extension (.ply or .pcd)");
}

void WritePointCloud(const fs::path& file, const PointCloud& cloud, PointCloudEncoding enc,
                     const PointAttributes* attributes) {
  const std::string ext = Lower(file.extension().string());
  if (ext == ".ply") return WritePly(file, cloud, enc, attributes);
  if (ext == ".pcd") return WritePcd(file, cloud, enc, attributes);
  throw Error(file.string() + ": unknown point cloud extension (.ply or .pcd)");
}

}  // namespace locforge

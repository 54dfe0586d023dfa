#include "kapture_out.h"

#include <algorithm>
#include <charconv>
#include <cstring>
#include <fstream>
#include <sstream>

#include "locforge/error.h"

namespace locforge::sim {

std::string FormatNumber(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);
  std::string s(buf, r.ptr);
  if (s.find_first_of(".en") == std::string::npos) s += ".0";  // keep floats recognisable
  return s;
}

std::string FormatPose(const Pose& p) {
  const Eigen::Quaterniond q = p.q.normalized();
  std::string s;
  for (double v : {q.w(), q.x(), q.y(), q.z(), p.t.x(), p.t.y(), p.t.z()})
    s += (s.empty() ? "" : ", ") + FormatNumber(v);
  return s;
}

void AddRigSensors(const Rig& rig, KaptureRows* rows) {
  for (const auto& c : rig.cameras) {
    const PinholeCamera& k = c.intrinsics;
    rows->sensors.push_back(c.id + ", " + c.model + ", camera, PINHOLE, " + std::to_string(k.width) + ", " +
                            std::to_string(k.height) + ", " + FormatNumber(k.fx) + ", " + FormatNumber(k.fy) +
                            ", " + FormatNumber(k.cx) + ", " + FormatNumber(k.cy));
  }
  for (const auto& l : rig.lidars) rows->sensors.push_back(l.id + ", Velodyne VLP-16, lidar");
  rows->sensors.push_back("wheels, differential drive encoders, wheel_encoder, " +
                          FormatNumber(rig.wheels.radius) + ", " + FormatNumber(rig.wheels.axle) + ", " +
                          std::to_string(rig.wheels.pulses_per_rev));
}

void AddRigExtrinsics(const Rig& rig, KaptureRows* rows) {
  // rigs.txt holds T_sensor_rig (rig frame -> sensor frame); the rig frame is the platform's.
  for (const auto& c : rig.cameras)
    rows->rigs.push_back("rig, " + c.id + ", " + FormatPose(c.T_platform_camera.Inverse()));
  for (const auto& l : rig.lidars)
    rows->rigs.push_back("rig, " + l.id + ", " + FormatPose(l.T_platform_lidar.Inverse()));
  rows->rigs.push_back("rig, wheels, " + FormatPose(Pose()));
}

void WriteDataFile(const fs::path& path, std::string_view bytes) {
  fs::create_directories(path.parent_path());
  const fs::path temp = TempSibling(path);
  {
    std::ofstream out(temp, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) {
      std::error_code ec;
      fs::remove(temp, ec);
      throw Error("cannot write " + path.string());
    }
  }
  std::error_code ec;
  fs::rename(temp, path, ec);
  if (ec) {
    fs::remove(temp, ec);
    throw Error("cannot write " + path.string() + ": " + ec.message());
  }
}

namespace {

std::string Header(const char* columns) {
  return std::string("# kapture format: 1.1\n# ") + columns + "\n";
}

void WriteTimed(const fs::path& path, const char* columns, std::vector<KaptureRows::Timed> rows,
                bool always) {
  if (rows.empty() && !always) return;
  std::stable_sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) {
    return a.timestamp != b.timestamp ? a.timestamp < b.timestamp : a.device < b.device;
  });
  std::string out = Header(columns);
  for (const auto& r : rows) out += std::to_string(r.timestamp) + ", " + r.device + ", " + r.rest + "\n";
  WriteFileAtomic(path, out);
}

}  // namespace

void WriteKaptureText(const fs::path& root, KaptureRows rows) {
  const fs::path s = root / "sensors";
  std::string sensors = Header("sensor_device_id, name, sensor_type, [sensor_params]+");
  for (const auto& line : rows.sensors) sensors += line + "\n";
  WriteFileAtomic(s / "sensors.txt", sensors);
  std::string rigs = Header("rig_device_id, sensor_device_id, qw, qx, qy, qz, tx, ty, tz");
  for (const auto& line : rows.rigs) rigs += line + "\n";
  WriteFileAtomic(s / "rigs.txt", rigs);
  WriteTimed(s / "trajectories.txt", "timestamp, device_id, qw, qx, qy, qz, tx, ty, tz",
             std::move(rows.trajectories), true);
  WriteTimed(s / "records_camera.txt", "timestamp, device_id, image_path", std::move(rows.records_camera), true);
  WriteTimed(s / "records_lidar.txt", "timestamp, device_id, point_cloud_path", std::move(rows.records_lidar), false);
  WriteTimed(s / "records_wheel_encoder.txt", "timestamp, device_id, left_ticks, right_ticks",
             std::move(rows.records_wheel), false);
}

namespace {
#pragma pack(push, 1)
struct PcdPoint {
  float x, y, z, intensity;
  uint16_t ring;
  double time;
};
#pragma pack(pop)
static_assert(sizeof(PcdPoint) == 26, "PCD record layout");
}  // namespace

std::string EncodePcd(const LidarScan& scan) {
  const size_t n = scan.points.size();
  std::ostringstream h;
  h << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
    << "FIELDS x y z intensity ring time\nSIZE 4 4 4 4 2 8\nTYPE F F F F U F\nCOUNT 1 1 1 1 1 1\n"
    << "WIDTH " << n << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << n << "\nDATA binary\n";
  std::string out = h.str();
  const size_t header = out.size();
  out.resize(header + n * sizeof(PcdPoint));
  for (size_t i = 0; i < n; ++i) {
    const LidarPoint& p = scan.points[i];
    const PcdPoint rec{p.xyz.x(), p.xyz.y(), p.xyz.z(), p.intensity, p.ring, p.time};
    std::memcpy(&out[header + i * sizeof(PcdPoint)], &rec, sizeof(PcdPoint));
  }
  return out;
}

LidarScan DecodePcd(const std::string& bytes, const std::string& file) {
  const std::string marker = "DATA binary\n";
  const size_t at = bytes.find(marker);
  if (at == std::string::npos) throw InputError(file, 0, "DATA", "not a binary PCD");
  if (bytes.find("FIELDS x y z intensity ring time") == std::string::npos)
    throw InputError(file, 0, "FIELDS", "expected fields x y z intensity ring time");
  const size_t points_at = bytes.find("\nPOINTS ");
  if (points_at == std::string::npos) throw InputError(file, 0, "POINTS", "missing");
  const size_t n = std::stoull(bytes.substr(points_at + 8));
  const size_t data = at + marker.size();
  if (bytes.size() != data + n * sizeof(PcdPoint))
    throw InputError(file, 0, "DATA", "size does not match POINTS " + std::to_string(n));
  LidarScan scan;
  scan.points.resize(n);
  for (size_t i = 0; i < n; ++i) {
    PcdPoint rec;
    std::memcpy(&rec, &bytes[data + i * sizeof(PcdPoint)], sizeof(PcdPoint));
    scan.points[i].xyz = {rec.x, rec.y, rec.z};
    scan.points[i].intensity = rec.intensity;
    scan.points[i].ring = rec.ring;
    scan.points[i].time = rec.time;
  }
  return scan;
}

}  // namespace locforge::sim

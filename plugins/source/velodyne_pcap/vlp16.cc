#include "vlp16.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "locforge/error.h"
#include "pcap.h"
#include "locforge/units.h"

namespace locforge::velodyne {

namespace {

constexpr int64_t kBlockPeriodNs = 2 * kSequencePeriodNs;  // two firing sequences

uint16_t Le16(const unsigned char* p) { return static_cast<uint16_t>(p[0] | p[1] << 8); }

void AssignRings(Calibration* c) {
  std::vector<int> order(c->lasers.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return c->lasers[a].vert_correction < c->lasers[b].vert_correction;
  });
  for (size_t r = 0; r < order.size(); ++r) c->lasers[order[r]].ring = static_cast<int>(r);
}

// One return of laser `laser` at `azimuth_deg` (the ROS velodyne_pointcloud
// model), in the ROS frame (x forward, y left, z up).
Eigen::Vector3f ToPoint(const LaserCalibration& l, double distance, double azimuth_deg) {
  const double cos_v = std::cos(l.vert_correction), sin_v = std::sin(l.vert_correction);
  const double a = azimuth_deg * kDeg - l.rot_correction;
  const double xy = distance * cos_v - l.vert_offset_correction * sin_v;
  // Velodyne's frame: y forward, x right, azimuth clockwise from y.
  const double x = xy * std::sin(a) - l.horiz_offset_correction * std::cos(a);
  const double y = xy * std::cos(a) + l.horiz_offset_correction * std::sin(a);
  const double z = distance * sin_v + l.vert_offset_correction * cos_v;
  return Eigen::Vector3f(static_cast<float>(y), static_cast<float>(-x), static_cast<float>(z));
}

}  // namespace

Calibration Calibration::Vlp16() {
  Calibration c;
  for (int i = 0; i < kLasers; ++i) {
    LaserCalibration l;
    // -15, 1, -13, 3, ..., -1, 15 deg: even ids look down, odd ids up.
    l.vert_correction = (i % 2 == 0 ? -15 + i : i) * kDeg;
    c.lasers.push_back(l);
  }
  AssignRings(&c);
  return c;
}

Calibration Calibration::FromYaml(const std::filesystem::path& file) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw InputError(file.string(), e.mark.line + 1, "", "not a calibration YAML: " + e.msg);
  }
  if (!root.IsMap() || !root["lasers"] || !root["lasers"].IsSequence())
    throw InputError(file.string(), 1, "lasers", "expected a list of lasers (velodyne_pointcloud calibration)");
  Calibration c;
  c.lasers.resize(kLasers);
  std::vector<bool> seen(kLasers, false);
  auto number = [&](const YAML::Node& n, const char* key, int line) {
    if (!n[key]) return 0.0;
    try {
      return n[key].as<double>();
    } catch (const YAML::Exception&) {
      throw InputError(file.string(), line, key, "expected a number");
    }
  };
  for (const auto& n : root["lasers"]) {
    const int line = n.Mark().line + 1;
    if (!n.IsMap() || !n["laser_id"]) throw InputError(file.string(), line, "laser_id", "each laser needs its laser_id");
    const double id = number(n, "laser_id", line);
    if (id < 0 || id >= kLasers || id != std::floor(id))
      throw InputError(file.string(), line, "laser_id",
                       "laser " + std::to_string(id) + " is not one of a VLP-16's 0..15");
    const int i = static_cast<int>(id);
    if (seen[i]) throw InputError(file.string(), line, "laser_id", "laser " + std::to_string(i) + " given twice");
    seen[i] = true;
    LaserCalibration& l = c.lasers[i];
    l.vert_correction = number(n, "vert_correction", line);
    l.rot_correction = number(n, "rot_correction", line);
    l.dist_correction = number(n, "dist_correction", line);
    l.vert_offset_correction = number(n, "vert_offset_correction", line);
    l.horiz_offset_correction = number(n, "horiz_offset_correction", line);
    if (std::abs(l.vert_correction) > M_PI / 2)
      throw InputError(file.string(), line, "vert_correction", "elevation beyond 90 deg: expected radians");
    for (const char* unused : {"dist_correction_x", "dist_correction_y", "focal_distance", "focal_slope"})
      if (number(n, unused, line) != 0) c.not_applied.push_back("laser " + std::to_string(i) + ": " + unused);
  }
  for (int i = 0; i < kLasers; ++i)
    if (!seen[i]) throw InputError(file.string(), 0, "lasers", "laser " + std::to_string(i) + " is missing");
  if (root["num_lasers"] && number(root, "num_lasers", 1) != kLasers)
    throw InputError(file.string(), 0, "num_lasers", "expected 16 (a VLP-16)");
  if (root["distance_resolution"]) {
    c.distance_resolution = number(root, "distance_resolution", 1);
    if (!(c.distance_resolution > 0 && c.distance_resolution < 0.1))
      throw InputError(file.string(), 0, "distance_resolution", "expected metres per unit, e.g. 0.002");
  }
  AssignRings(&c);
  return c;
}

Returns ParseReturns(const std::string& text) {
  if (text == "auto") return Returns::kAuto;
  if (text == "strongest") return Returns::kStrongest;
  if (text == "last") return Returns::kLast;
  if (text == "dual") return Returns::kDual;
  throw ParamError("returns: '" + text + "' is not one of auto, strongest, last, dual");
}

bool DecodePacket(const std::string& payload, int64_t packet_time_ns, const Calibration& calibration,
                  const DecodeOptions& options, std::vector<Point>* points, DecodeStats* stats) {
  const auto* p = reinterpret_cast<const unsigned char*>(payload.data());
  bool valid = payload.size() == kPacketSize;
  for (int b = 0; valid && b < kBlocks; ++b)
    valid = p[b * 100] == 0xff && p[b * 100 + 1] == 0xee && Le16(p + b * 100 + 2) < 36000;
  const uint8_t mode = valid ? p[1204] : 0;
  valid = valid && (mode == kReturnStrongest || mode == kReturnLast || mode == kReturnDual);
  if (!valid) {
    ++stats->bad_packets;
    return false;
  }
  ++stats->packets;
  stats->return_mode = mode;
  stats->product_id = p[1205];
  const bool dual = mode == kReturnDual;
  Returns want = options.returns;
  if (want == Returns::kAuto) want = dual ? Returns::kDual : Returns::kStrongest;
  if (!dual && ((want == Returns::kStrongest && mode != kReturnStrongest) ||
                (want == Returns::kLast && mode != kReturnLast) || want == Returns::kDual))
    throw ParamError(std::string("returns: the capture holds ") + (mode == kReturnLast ? "last" : "strongest") +
                     " returns only (the sensor's return mode); set returns to auto or " +
                     (mode == kReturnLast ? "last" : "strongest"));
  const int step = dual ? 2 : 1;  // blocks per firing pair
  auto azimuth = [&](int b) { return Le16(p + b * 100 + 2) / 100.0; };
  for (int b = 0; b < kBlocks; b += step) {
    const double az = azimuth(b);
    // Degrees the head turns over one block: to the next firing pair, or
    // from the previous one for the last.
    double gap = b + step < kBlocks ? azimuth(b + step) - az : az - azimuth(b - step);
    if (gap < 0) gap += 360;
    if (gap > 5) gap = 0;  // a gap in the data: no interpolation rather than a wrong one
    const int64_t block_ns = (b / step) * kBlockPeriodNs;
    for (int s = 0; s < 2; ++s)
      for (int laser = 0; laser < kLasers; ++laser) {
        const int64_t offset_ns = s * kSequencePeriodNs + laser * kLaserSpacingNs;
        const double point_az = std::fmod(az + gap * static_cast<double>(offset_ns) / kBlockPeriodNs, 360.0);
        ++stats->firings;
        struct Return {
          uint16_t distance;
          uint8_t reflectivity;
        };
        auto read = [&](int block) {
          const unsigned char* c = p + block * 100 + 4 + (s * kLasers + laser) * 3;
          return Return{Le16(c), c[2]};
        };
        Return returns[2];
        int count = 0;
        const Return first = read(b);
        if (!dual) {
          returns[count++] = first;
        } else {
          const Return other = read(b + 1);  // strongest, or second strongest when the strongest is the last
          if (want == Returns::kLast) {
            returns[count++] = first;
          } else if (want == Returns::kStrongest) {
            returns[count++] = first.reflectivity >= other.reflectivity ? first : other;
          } else {
            returns[count++] = first;
            if (other.distance != first.distance || other.reflectivity != first.reflectivity) returns[count++] = other;
          }
        }
        for (int r = 0; r < count; ++r) {
          if (returns[r].distance == 0) {
            ++stats->no_return;
            continue;
          }
          const LaserCalibration& l = calibration.lasers[laser];
          const double distance = returns[r].distance * calibration.distance_resolution + l.dist_correction;
          if (distance < options.min_range || distance > options.max_range) {
            ++stats->out_of_range;
            continue;
          }
          Point pt;
          pt.xyz = ToPoint(l, distance, point_az);
          pt.intensity = returns[r].reflectivity;
          pt.ring = static_cast<uint16_t>(l.ring);
          pt.time_ns = packet_time_ns + block_ns + offset_ns;
          pt.azimuth_deg = point_az;
          points->push_back(pt);
        }
      }
  }
  return true;
}

int64_t PacketClock::TimeNs(uint32_t micros_past_hour, double capture_time) {
  const int64_t micros = micros_past_hour;
  if (!started_) {
    started_ = true;
    anchor_ns_ = static_cast<int64_t>(std::llround(capture_time * 1e6)) * 1000;
    first_micros_ = last_micros_ = micros;
  }
  // The sensor's clock wraps at the top of the hour; a step back by more
  // than half an hour is a wrap (a small step back is a reordered packet).
  if (micros < last_micros_ - 1800000000LL) ++hours_;
  last_micros_ = micros;
  return anchor_ns_ + (micros + hours_ * 3600000000LL - first_micros_) * 1000;
}

void ScanAssembler::Emit(bool complete, std::vector<Scan>* scans) {
  if (current_.points.empty()) return;
  current_.complete = complete;
  current_.azimuth_span_deg = span_;
  scans->push_back(std::move(current_));
  current_ = Scan();
  span_ = 0;
  ++emitted_;
}

void ScanAssembler::Add(const std::vector<Point>& points, std::vector<Scan>* scans) {
  for (const Point& pt : points) {
    if (!started_) {
      started_ = true;
      if (cut_ < 0) cut_ = pt.azimuth_deg;  // the stream starts a whole revolution
      first_complete_ = std::abs(pt.azimuth_deg - cut_) < 1.0;
      window_start_ns_ = pt.time_ns;
      last_angle_ = std::fmod(pt.azimuth_deg - cut_ + 360.0, 360.0);
    }
    const double angle = std::fmod(pt.azimuth_deg - cut_ + 360.0, 360.0);
    const bool wrapped = angle + 180.0 < last_angle_;  // past the cut
    if (period_ns_ > 0) {
      if (pt.time_ns >= window_start_ns_ + period_ns_) {
        Emit(true, scans);  // windows start at the first point: each is whole
        while (pt.time_ns >= window_start_ns_ + period_ns_) window_start_ns_ += static_cast<int64_t>(period_ns_);
      }
    } else if (wrapped) {
      Emit(emitted_ > 0 || first_complete_, scans);
    }
    if (!current_.points.empty()) span_ += wrapped ? angle + 360.0 - last_angle_ : std::max(0.0, angle - last_angle_);
    last_angle_ = angle;
    current_.points.push_back(pt);
  }
}

void ScanAssembler::Finish(std::vector<Scan>* scans) { Emit(false, scans); }

CaptureScans ScanCapture(const std::filesystem::path& pcap, const Calibration& calibration,
                         const CaptureOptions& options, const std::function<void()>& between_packets) {
  CaptureScans out;
  PcapReader reader(pcap);
  PacketClock clock;
  ScanAssembler assembler(options.cut_azimuth_deg, options.scan_period_s);
  UdpPacket packet;
  std::vector<Point> points;
  while (reader.Next(&packet)) {
    if (between_packets) between_packets();
    if (packet.destination_port != options.port) {
      ++out.other_ports;
      continue;
    }
    if (packet.payload.size() != kPacketSize) {
      ++out.stats.bad_packets;
      continue;
    }
    const auto* p = reinterpret_cast<const unsigned char*>(packet.payload.data());
    const uint32_t micros = static_cast<uint32_t>(p[1200]) | static_cast<uint32_t>(p[1201]) << 8 |
                            static_cast<uint32_t>(p[1202]) << 16 | static_cast<uint32_t>(p[1203]) << 24;
    points.clear();
    if (DecodePacket(packet.payload, clock.TimeNs(micros, packet.capture_time), calibration, options.decode,
                     &points, &out.stats))
      assembler.Add(points, &out.scans);
  }
  assembler.Finish(&out.scans);
  out.udp = reader.stats().udp;
  if (out.stats.packets == 0)
    throw InputError(pcap.string(), 0, "",
                     "no VLP-16 data packet on UDP port " + std::to_string(options.port) + " (" +
                         std::to_string(out.udp) + " UDP datagrams, " + std::to_string(out.stats.bad_packets) +
                         " of 1206 bytes or malformed on that port)");
  return out;
}

}  // namespace locforge::velodyne

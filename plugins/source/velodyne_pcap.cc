// source/velodyne_pcap: a Velodyne VLP-16 packet capture (pcap) -> a kapture
// dataset of LiDAR records, one PCD per scan with each point's firing time
// (velodyne_pcap/: pcap reading, packet decoding, scans).
#include <cmath>
#include <sstream>

#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "locforge/pointcloud_io.h"
#include "vlp16.h"

namespace locforge::source {

using namespace ::locforge::velodyne;  // the library this stage wires

namespace {

namespace kp = locforge::kapture;

struct VelodynePcapOptions {
  std::string pcap;         // The capture.
  std::string calibration;  // velodyne_pointcloud YAML; empty: the VLP-16 datasheet.
  int64_t port = 2368;      // UDP destination port of the data packets.
  std::string returns = "auto";
  double cut_azimuth_deg = -1;  // -1: where the capture starts.
  double scan_period_s = 0;     // 0: one scan per revolution.
  bool keep_partial = false;
  double min_range_m = 0;
  double max_range_m = 200;
  std::string sensor_id = "lidar0";
  std::string sequence = "vlp16";

  static void Declare(ParamSchema<VelodynePcapOptions>& s) {
    using O = VelodynePcapOptions;
    s.Add("pcap", &O::pcap, "Packet capture of the sensor (classic pcap: tcpdump, Wireshark, VeloView)")
        .Path()
        .Required();
    s.Add("calibration", &O::calibration,
          "velodyne_pointcloud calibration YAML (per-laser angles and offsets); empty: the VLP-16 datasheet's")
        .Path();
    s.Add("port", &O::port, "UDP destination port of the data packets (position packets go to 8308)")
        .Range(1, 65535);
    s.Add("returns", &O::returns,
          "auto: what the sensor sent (both returns in dual mode); strongest, last or dual (dual-mode captures)")
        .Choices({"auto", "strongest", "last", "dual"});
    s.Add("cut_azimuth_deg", &O::cut_azimuth_deg,
          "Azimuth where a revolution ends (deg, 0 = forward, clockwise seen from above); -1: where the capture "
          "starts")
        .Range(-1, 360);
    s.Add("scan_period_s", &O::scan_period_s, "One scan per this many seconds instead of per revolution (0: per revolution)")
        .Range(0, 10);
    s.Add("keep_partial", &O::keep_partial,
          "Keep the scans cut short by the start or end of the capture");
    s.Add("min_range_m", &O::min_range_m, "Closer returns are dropped (m)").Range(0, 1000);
    s.Add("max_range_m", &O::max_range_m, "Farther returns are dropped (m)").Range(0, 1000);
    s.Add("sensor_id", &O::sensor_id, "kapture sensor id of the LiDAR");
    s.Add("sequence", &O::sequence, "Folder of the scans under records_data (<sequence>/<sensor_id>/<timestamp>.pcd)");
  }
  bool Check(std::string* why) const {
    if (min_range_m >= max_range_m) return *why = "min_range_m must be below max_range_m", false;
    if (sensor_id.empty() || sensor_id.find_first_of(", /") != std::string::npos)
      return *why = "sensor_id must be non-empty, without ',', ' ' or '/'", false;
    if (sequence.empty() || sequence.find("..") != std::string::npos || sequence[0] == '/')
      return *why = "sequence must be a relative folder name", false;
    return true;
  }
};

class VelodynePcap : public Stage<VelodynePcapOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta{"source", "velodyne_pcap",
                   "Velodyne VLP-16 packets (pcap) -> LiDAR scans with per-point firing time, ring and intensity, "
                   "as kapture LiDAR records (PCD, the simulator's layout) that lidar/preprocess undistorts",
                   {},
                   {{"dataset", "kapture.dataset", "sensors.txt, records_lidar.txt, records_data/<sequence>/<sensor>/"
                                                   "<timestamp>.pcd (x y z intensity ring time), scans.csv"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

void VelodynePcap::Run(RunContext& ctx) {
  const VelodynePcapOptions& o = options();
  const Calibration calibration =
      o.calibration.empty() ? Calibration::Vlp16() : Calibration::FromYaml(o.calibration);
  for (const auto& c : calibration.not_applied)
    ctx.Warn("velodyne_pcap: calibration term not applied (HDL-64 near-range or intensity model): " + c);
  CaptureOptions capture;
  capture.port = static_cast<int>(o.port);
  capture.decode = {ParseReturns(o.returns), o.min_range_m, o.max_range_m};
  capture.cut_azimuth_deg = o.cut_azimuth_deg;
  capture.scan_period_s = o.scan_period_s;
  const CaptureScans read = ScanCapture(o.pcap, calibration, capture, [&] { ctx.ThrowIfCancelled(); });
  const std::vector<Scan>& scans = read.scans;
  const DecodeStats& stats = read.stats;
  const int64_t other_ports = read.other_ports;

  const fs::path out = ctx.output_dir();
  kp::Sensors sensors;
  sensors.Add({o.sensor_id, "Velodyne VLP-16", kp::kSensorLidar, {}, std::nullopt});
  kp::WriteSensors(out / kp::layout::kSensors, sensors);
  std::vector<kp::DataRecord> records;
  std::ostringstream table;
  table << "timestamp,points,duration_s,azimuth_span_deg,complete,kept\n";
  int64_t kept = 0, dropped = 0;
  for (const Scan& scan : scans) {
    const bool keep = scan.complete || o.keep_partial;
    const int64_t start_ns = scan.points.front().time_ns;
    const int64_t timestamp = start_ns / 1000;  // kapture: microseconds, the scan's first firing
    table << timestamp << "," << scan.points.size() << ","
          << (scan.points.back().time_ns - start_ns) * 1e-9 << "," << scan.azimuth_span_deg << ","
          << (scan.complete ? 1 : 0) << "," << (keep ? 1 : 0) << "\n";
    if (!keep) {
      ++dropped;
      continue;
    }
    PointCloud cloud;
    PointAttributes attributes;
    cloud.points.reserve(scan.points.size());
    for (const Point& pt : scan.points) {
      cloud.points.push_back(pt.xyz);
      cloud.times.push_back((pt.time_ns - timestamp * 1000) * 1e-9);  // s after the record's timestamp
      attributes.intensity.push_back(pt.intensity);
      attributes.ring.push_back(pt.ring);
    }
    const std::string path = o.sequence + "/" + o.sensor_id + "/" + std::to_string(timestamp) + ".pcd";
    WritePcd(out / kp::layout::kRecordsData / path, cloud, PointCloudEncoding::kBinary, &attributes);
    records.push_back({timestamp, o.sensor_id, path});
    ++kept;
    ctx.Progress(kept, scans.size(), "scans");
  }
  if (records.empty())
    throw InputError(o.pcap, 0, "",
                     "no whole scan in the capture (" + std::to_string(scans.size()) +
                         " partial); set keep_partial: true to keep them, or scan_period_s for time windows");
  kp::WriteRecords(out / kp::layout::RecordsFile("lidar"), kp::RecordKind::kLidar, records);
  WriteFileAtomic(out / "scans.csv", table.str());
  char product[8];
  std::snprintf(product, sizeof(product), "0x%02x", stats.product_id);
  ctx.Info("velodyne_pcap: " + std::to_string(stats.packets) + " data packets (return mode " +
           (stats.return_mode == kReturnDual ? "dual" : stats.return_mode == kReturnLast ? "last" : "strongest") +
           ", product id " + product + "), " + std::to_string(kept) + " scans written, " + std::to_string(dropped) +
           " partial dropped, " + std::to_string(stats.no_return) + " firings without return, " +
           std::to_string(other_ports) + " packets on other ports");
  if (stats.bad_packets > 0)
    ctx.Warn("velodyne_pcap: " + std::to_string(stats.bad_packets) + " malformed packets on port " +
             std::to_string(o.port) + " skipped");
}

}  // namespace

LOCFORGE_REGISTER_STAGE(VelodynePcap)

}  // namespace locforge::source

// Velodyne VLP-16 data packets -> points with their own firing times, and
// points -> scans (one per revolution, or per time window). The packet
// layout and timing follow the VLP-16 user manual:
//   1206-byte UDP payload: 12 blocks of {0xFFEE, azimuth (0.01 deg),
//   32 x (distance in 2 mm units, reflectivity)}, a 4-byte timestamp (us past
//   the hour, of the packet's first firing), return mode (0x37 strongest,
//   0x38 last, 0x39 dual) and product id.
//   A block holds two firing sequences of the 16 lasers; a sequence lasts
//   55.296 us, laser i fires 2.304 us x i after its start. Single return:
//   block b starts at b x 110.592 us. Dual return: blocks 2k (last return)
//   and 2k+1 (strongest, or second strongest when the strongest is the last)
//   are the same firings, starting at k x 110.592 us.
//   Azimuths between two blocks are interpolated by firing time.
#ifndef LOCFORGE_PLUGINS_SOURCE_VELODYNE_PCAP_VLP16_H_
#define LOCFORGE_PLUGINS_SOURCE_VELODYNE_PCAP_VLP16_H_

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace locforge::velodyne {

inline constexpr int kLasers = 16;
inline constexpr int kBlocks = 12;
inline constexpr size_t kPacketSize = 1206;
inline constexpr int64_t kLaserSpacingNs = 2304;     // between lasers of a firing sequence
inline constexpr int64_t kSequencePeriodNs = 55296;  // one firing sequence
inline constexpr uint8_t kReturnStrongest = 0x37, kReturnLast = 0x38, kReturnDual = 0x39;

// One laser's calibration, the ROS velodyne_pointcloud model (angles in
// radians, lengths in metres).
struct LaserCalibration {
  double vert_correction = 0;          // elevation
  double rot_correction = 0;           // azimuth offset
  double dist_correction = 0;          // added to every range
  double vert_offset_correction = 0;   // along the sensor's axis
  double horiz_offset_correction = 0;  // sideways
  int ring = 0;                        // rank by elevation, 0 = lowest
};

struct Calibration {
  std::vector<LaserCalibration> lasers;  // by laser id
  double distance_resolution = 0.002;    // m per distance unit
  // Corrections of the file this decoder does not apply (HDL-64 near-range
  // and intensity terms): "laser 3: dist_correction_x", for a warning.
  std::vector<std::string> not_applied;

  // The VLP-16 datasheet: elevations -15, 1, -13, 3, ..., 15 deg by laser id.
  static Calibration Vlp16();
  // A velodyne_pointcloud calibration YAML (lasers: [{laser_id,
  // vert_correction, rot_correction, dist_correction, ...}], num_lasers,
  // distance_resolution). Throws InputError naming the file and field.
  static Calibration FromYaml(const std::filesystem::path& file);
};

// Which returns of the packets become points.
enum class Returns { kAuto, kStrongest, kLast, kDual };
// "auto" (what the packets hold), "strongest", "last", "dual"; throws ParamError otherwise.
Returns ParseReturns(const std::string& text);

struct Point {
  Eigen::Vector3f xyz;  // sensor frame, x forward, y left, z up (the ROS convention)
  float intensity = 0;  // reflectivity, 0..255
  uint16_t ring = 0;
  int64_t time_ns = 0;  // firing time
  double azimuth_deg = 0;  // of the firing, [0, 360)
};

struct DecodeStats {
  int64_t packets = 0, bad_packets = 0;
  int64_t firings = 0;       // laser firings seen (16 per firing sequence)
  int64_t no_return = 0;     // firings with distance 0
  int64_t out_of_range = 0;  // returns outside [min_range, max_range]
  uint8_t return_mode = 0;   // of the last packet
  uint8_t product_id = 0;
};

struct DecodeOptions {
  Returns returns = Returns::kAuto;
  double min_range = 0;    // m; 0 keeps every return
  double max_range = 200;  // m
};

// Decodes one 1206-byte data packet whose first firing is at
// `packet_time_ns`, appending its points in firing order. Returns false (and
// counts a bad packet) when the payload is not a VLP-16 data packet; throws
// ParamError when the returns asked for are not in the packet.
bool DecodePacket(const std::string& payload, int64_t packet_time_ns, const Calibration& calibration,
                  const DecodeOptions& options, std::vector<Point>* points, DecodeStats* stats);

// The sensor's clock: microseconds past the hour, wrapping. Unwraps it into
// a continuous time anchored at the first packet's capture time.
class PacketClock {
 public:
  int64_t TimeNs(uint32_t micros_past_hour, double capture_time);

 private:
  bool started_ = false;
  int64_t anchor_ns_ = 0;        // capture time of the first packet
  int64_t first_micros_ = 0;     // its sensor time
  int64_t hours_ = 0;            // wraps seen
  int64_t last_micros_ = 0;
};

struct Scan {
  std::vector<Point> points;  // in firing order
  bool complete = false;      // a whole revolution (or time window)
  double azimuth_span_deg = 0;
};

// Cuts the stream of points into scans: at the cut azimuth (one scan per
// revolution; cut_azimuth_deg < 0: where the stream starts), or every
// period_s seconds when period_s > 0.
class ScanAssembler {
 public:
  ScanAssembler(double cut_azimuth_deg, double period_s) : cut_(cut_azimuth_deg), period_ns_(period_s * 1e9) {}
  // Adds points; finished scans are appended to `scans`.
  void Add(const std::vector<Point>& points, std::vector<Scan>* scans);
  // The scan in progress (incomplete), if any.
  void Finish(std::vector<Scan>* scans);

 private:
  void Emit(bool complete, std::vector<Scan>* scans);

  double cut_;
  double period_ns_;
  bool started_ = false;
  bool first_complete_ = false;  // the stream's first scan starts at the cut
  int64_t emitted_ = 0;
  double last_angle_ = 0;        // azimuth past the cut, [0, 360)
  double span_ = 0;
  int64_t window_start_ns_ = 0;
  Scan current_;
};

// A whole capture: its data packets on one UDP port, decoded and cut into
// scans.
struct CaptureOptions {
  int port = 2368;  // UDP destination port of the data packets
  DecodeOptions decode;
  double cut_azimuth_deg = -1;  // ScanAssembler
  double scan_period_s = 0;
};

struct CaptureScans {
  std::vector<Scan> scans;
  DecodeStats stats;
  int64_t udp = 0;          // UDP datagrams in the capture
  int64_t other_ports = 0;  // datagrams to other ports (position packets: 8308)
};

// Reads `pcap` (PcapReader) through the decoder and the scan assembler;
// `between_packets` (may be empty) runs before each packet, e.g. to cancel.
// Throws InputError when the capture holds no data packet on the port.
CaptureScans ScanCapture(const std::filesystem::path& pcap, const Calibration& calibration,
                         const CaptureOptions& options, const std::function<void()>& between_packets = {});

}  // namespace locforge::velodyne

#endif  // LOCFORGE_PLUGINS_SOURCE_VELODYNE_PCAP_VLP16_H_

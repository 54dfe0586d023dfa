// VLP-16 decoding on a real capture (../shared/data/lidar/vlp16_packets: one
// revolution and a bit, strongest returns, its calibration file) and on
// packets built here with known answers (dual returns, firing times), plus
// the pcap reader's refusals.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstring>
#include <fstream>
#include <random>
#include <set>

#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/pointcloud_io.h"
#include "locforge/runtime/registry.h"
#include "locforge/testkit.h"
#include "pcap.h"
#include "testing.h"
#include "vlp16.h"

namespace locforge::velodyne {
namespace {

struct Decoded {
  std::vector<Scan> scans;
  DecodeStats stats;
  int64_t packets = 0;
};

Decoded Decode(const fs::path& pcap, const Calibration& calibration, double cut = -1, double period = 0) {
  CaptureOptions options;
  options.cut_azimuth_deg = cut;
  options.scan_period_s = period;
  CaptureScans c = ScanCapture(pcap, calibration, options);
  return {std::move(c.scans), c.stats, c.stats.packets};
}

// The returns of the capture's data packets, counted from the raw bytes
// without the decoder: Ethernet + 20-byte IPv4 + UDP headers, then 12
// blocks of 32 (distance, reflectivity) channels.
int64_t RawReturns(const fs::path& pcap, int64_t* firings) {
  const std::string bytes = ReadFile(pcap);
  int64_t returns = 0;
  *firings = 0;
  for (size_t at = 24; at + 16 <= bytes.size();) {
    uint32_t length = 0;
    std::memcpy(&length, bytes.data() + at + 8, 4);
    const auto* frame = reinterpret_cast<const unsigned char*>(bytes.data() + at + 16);
    at += 16 + length;
    if (length != 42 + 1206 || (frame[36] << 8 | frame[37]) != 2368) continue;
    for (int b = 0; b < 12; ++b)
      for (int c = 0; c < 32; ++c) {
        const unsigned char* ch = frame + 42 + b * 100 + 4 + c * 3;
        ++*firings;
        returns += (ch[0] | ch[1] << 8) != 0;
      }
  }
  return returns;
}

// The plane through most points (RANSAC, then least squares on its
// inliers): unit normal n and offset d with n.p + d = 0.
struct Plane {
  Eigen::Vector3d normal;
  double offset = 0;
  std::vector<size_t> inliers;
  double rms = 0;
};

Plane FitLargestPlane(const std::vector<Point>& points, double threshold) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<size_t> pick(0, points.size() - 1);
  Plane best;
  for (int iteration = 0; iteration < 400; ++iteration) {
    const Eigen::Vector3d a = points[pick(rng)].xyz.cast<double>(), b = points[pick(rng)].xyz.cast<double>(),
                          c = points[pick(rng)].xyz.cast<double>();
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-6) continue;
    n.normalize();
    std::vector<size_t> in;
    for (size_t i = 0; i < points.size(); ++i)
      if (std::abs(n.dot(points[i].xyz.cast<double>() - a)) < threshold) in.push_back(i);
    if (in.size() > best.inliers.size()) best = {n, -n.dot(a), in, 0};
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (size_t i : best.inliers) mean += points[i].xyz.cast<double>();
  mean /= static_cast<double>(best.inliers.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t i : best.inliers) {
    const Eigen::Vector3d d = points[i].xyz.cast<double>() - mean;
    cov += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  best.normal = eig.eigenvectors().col(0);
  best.offset = -best.normal.dot(mean);
  double sq = 0;
  for (size_t i : best.inliers) sq += std::pow(best.normal.dot(points[i].xyz.cast<double>()) + best.offset, 2);
  best.rms = std::sqrt(sq / best.inliers.size());
  return best;
}

TEST(Vlp16, SharedCaptureOneRevolution) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, "data/lidar/vlp16_packets");
  const Calibration calibration = Calibration::FromYaml(dir / "VLP16db.yaml");
  EXPECT_TRUE(calibration.not_applied.empty());
  const Decoded d = Decode(dir / "velodyne_vlp16.pcap", calibration);
  EXPECT_EQ(d.packets, 84);  // the 16 position packets go to port 8308
  EXPECT_EQ(d.stats.bad_packets, 0);
  EXPECT_EQ(d.stats.return_mode, kReturnStrongest);
  // Every return of the packets is a point, once: counted from the raw bytes.
  int64_t firings = 0;
  const int64_t raw = RawReturns(dir / "velodyne_vlp16.pcap", &firings);
  size_t points = 0;
  for (const Scan& s : d.scans) points += s.points.size();
  EXPECT_EQ(static_cast<int64_t>(points), raw);
  EXPECT_EQ(d.stats.firings, firings);

  // The capture starts a revolution, then stops 0.1 revolution into the next.
  ASSERT_EQ(d.scans.size(), 2u);
  const Scan& scan = d.scans[0];
  EXPECT_TRUE(scan.complete);
  EXPECT_FALSE(d.scans[1].complete);
  EXPECT_NEAR(scan.azimuth_span_deg, 360, 0.5);
  // Points per revolution: 16 lasers x the firing sequences of one turn
  // (the head turns 0.2 deg per 55.296 us sequence at 600 rpm), less the
  // firings without a return (sky, beyond range: 38% of this capture's
  // firings). A sequence starts laser x 2.304 us before a point of that
  // laser.
  std::vector<int> laser_of_ring(16);
  for (int i = 0; i < 16; ++i) laser_of_ring[calibration.lasers[i].ring] = i;
  std::set<int64_t> sequences;
  for (const Point& p : scan.points) sequences.insert(p.time_ns - laser_of_ring[p.ring] * kLaserSpacingNs);
  const double duration = (scan.points.back().time_ns - scan.points.front().time_ns) * 1e-9;
  std::cout << "revolution: " << scan.points.size() << " points, " << sequences.size() << " firing sequences, "
            << duration * 1e3 << " ms (" << 60.0 / duration << " rpm)\n";
  EXPECT_NEAR(static_cast<double>(sequences.size()), duration / 55.296e-6, 1.5);
  EXPECT_NEAR(static_cast<double>(sequences.size()), 360.0 / 0.2, 40);  // 570..630 rpm
  EXPECT_GT(scan.points.size(), 0.5 * 16 * sequences.size());
  EXPECT_LE(scan.points.size(), 16 * sequences.size());
  // The datasheet's timing agrees with the sensor's own clock: consecutive
  // sequences 55.296 us apart, also across packets, whose timestamps are
  // whole microseconds.
  for (auto it = std::next(sequences.begin()); it != sequences.end(); ++it)
    ASSERT_NEAR(static_cast<double>(*it - *std::prev(it)), kSequencePeriodNs, 1000.0) << *it;

  // Per-ring elevation: the calibration's angle of the laser, exactly
  // (float rounding), rings ordered from -15 to +15 deg by 2.
  std::vector<double> elevation(16, 0);
  std::vector<int64_t> per_ring(16, 0);
  for (const Point& p : scan.points) {
    const double e = std::asin(p.xyz.z() / p.xyz.norm());
    if (per_ring[p.ring]++ == 0) elevation[p.ring] = e;
    ASSERT_NEAR(e, elevation[p.ring], 2e-5) << "ring " << p.ring;
  }
  for (int r = 0; r < 16; ++r) {
    EXPECT_NEAR(elevation[r] * 180 / M_PI, -15 + 2 * r, 1e-3) << "ring " << r;
    EXPECT_GT(per_ring[r], 400) << "ring " << r;  // every laser returns in every direction class
  }

  // Per-point times: strictly increasing in firing order (one return per
  // firing in a strongest-return capture).
  for (size_t i = 1; i < scan.points.size(); ++i) ASSERT_GT(scan.points[i].time_ns, scan.points[i - 1].time_ns) << i;
  EXPECT_NEAR(duration, 0.0995, 0.003);

  // A flat surface: the largest plane of the scan (the ground, 1.8 m below
  // the sensor) is level and holds thousands of points at the datasheet's
  // +-3 cm accuracy. A wrong elevation, azimuth or offset bends it.
  const Plane plane = FitLargestPlane(scan.points, 0.05);
  std::cout << "largest plane: " << plane.inliers.size() << " points, normal " << plane.normal.transpose()
            << ", offset " << plane.offset << " m, RMS " << plane.rms * 100 << " cm\n";
  EXPECT_GT(plane.inliers.size(), 3000u);
  EXPECT_GT(std::abs(plane.normal.z()), std::cos(5 * M_PI / 180));
  EXPECT_LT(plane.rms, 0.03);
}

TEST(Vlp16, StageWritesScansWithPerPointTimes) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, "data/lidar/vlp16_packets");
  const fs::path out = locforge::testing::MakeTempDir("velodyne_pcap");
  runtime::Registry registry;
  ASSERT_TRUE(registry.LoadFile(LOCFORGE_SOURCE_PLUGIN_FILE));
  testkit::RunStage(registry, "source/velodyne_pcap",
                    {{"pcap", (dir / "velodyne_vlp16.pcap").string()}, {"calibration", (dir / "VLP16db.yaml").string()}},
                    {}, out / "revolution");
  const kapture::Kapture k(out / "revolution");
  const auto records = k.ReadDataRecords("lidar");
  ASSERT_EQ(records.size(), 1u);  // the partial second revolution is dropped
  EXPECT_EQ(k.sensors().Find("lidar0")->type, "lidar");
  PointAttributes attributes;
  const PointCloud cloud = ReadPointCloud(k.ExistingRecordDataPath(records[0].path), &attributes);
  ASSERT_TRUE(cloud.has_times());
  ASSERT_EQ(attributes.ring.size(), cloud.size());
  ASSERT_EQ(attributes.intensity.size(), cloud.size());
  EXPECT_DOUBLE_EQ(cloud.times.front(), 0.0);
  EXPECT_TRUE(std::is_sorted(cloud.times.begin(), cloud.times.end()));
  EXPECT_NEAR(cloud.times.back(), 0.0995, 0.003);
  EXPECT_EQ(*std::max_element(attributes.ring.begin(), attributes.ring.end()), 15);

  // Time windows of 40 ms: two whole ones in the 111 ms capture, the rest dropped.
  testkit::RunStage(registry, "source/velodyne_pcap",
                    {{"pcap", (dir / "velodyne_vlp16.pcap").string()}, {"scan_period_s", "0.04"}}, {}, out / "windows");
  const auto windows = kapture::Kapture(out / "windows").ReadDataRecords("lidar");
  ASSERT_EQ(windows.size(), 2u);
  EXPECT_NEAR(static_cast<double>(windows[1].timestamp - windows[0].timestamp), 40000, 60);
  fs::remove_all(out);
}

// A dual-return packet built here: laser i of block pair k returns at
// distance (k, i) in the last-return block and at another in the strongest.
std::string DualPacket() {
  std::string p(kPacketSize, '\0');
  auto* b = reinterpret_cast<unsigned char*>(p.data());
  for (int block = 0; block < kBlocks; ++block) {
    unsigned char* h = b + block * 100;
    h[0] = 0xff, h[1] = 0xee;
    const uint16_t azimuth = static_cast<uint16_t>((block / 2) * 40);  // 0.4 deg per firing pair
    h[2] = azimuth & 0xff, h[3] = azimuth >> 8;
    for (int c = 0; c < 32; ++c) {
      const bool last = block % 2 == 0;
      // Last return 10 m + 1 cm x channel, reflectivity 10; strongest 5 m,
      // reflectivity 200 -- except channel 0, whose strongest is its last.
      const uint16_t distance = static_cast<uint16_t>(last || c == 0 ? 5000 + 5 * c : 2500);
      unsigned char* ch = h + 4 + c * 3;
      ch[0] = distance & 0xff, ch[1] = distance >> 8;
      ch[2] = last || c == 0 ? (c == 0 ? 200 : 10) : 200;
    }
  }
  b[1204] = kReturnDual;
  b[1205] = 0x22;
  return p;
}

TEST(Vlp16, DualReturnsAndFiringTimes) {
  const Calibration calibration = Calibration::Vlp16();
  const std::string packet = DualPacket();
  auto decode = [&](Returns r) {
    DecodeOptions o;
    o.returns = r;
    std::vector<Point> points;
    DecodeStats stats;
    EXPECT_TRUE(DecodePacket(packet, 1000000000, calibration, o, &points, &stats));
    return points;
  };
  const std::vector<Point> last = decode(Returns::kLast), strongest = decode(Returns::kStrongest),
                           dual = decode(Returns::kDual);
  // 6 firing pairs x 2 sequences x 16 lasers.
  ASSERT_EQ(last.size(), 192u);
  ASSERT_EQ(strongest.size(), 192u);
  // Channel 0 (laser 0 of the first sequence) has one return: not doubled.
  EXPECT_EQ(dual.size(), 192u * 2 - 6);
  EXPECT_NEAR(last[1].xyz.norm(), 10.01, 1e-4);
  EXPECT_NEAR(strongest[1].xyz.norm(), 5.0, 1e-4);
  EXPECT_NEAR(strongest[0].xyz.norm(), 10.0, 1e-4);  // the strongest was the last
  EXPECT_EQ(strongest[1].intensity, 200);
  // Firing times: pair k at k x 110.592 us, sequence s at + s x 55.296 us,
  // laser i at + i x 2.304 us; azimuth interpolated between pairs.
  for (size_t i = 0; i < last.size(); ++i) {
    const int64_t k = i / 32, s = (i / 16) % 2, laser = i % 16;
    EXPECT_EQ(last[i].time_ns, 1000000000 + k * 110592 + s * 55296 + laser * 2304) << i;
    EXPECT_NEAR(last[i].azimuth_deg, 0.4 * k + 0.4 * (s * 55296 + laser * 2304) / 110592.0, 1e-9) << i;
  }
  // A single-return capture cannot give the other return.
  std::string single = packet;
  single[1204] = static_cast<char>(kReturnStrongest);
  DecodeOptions want_last;
  want_last.returns = Returns::kLast;
  std::vector<Point> points;
  DecodeStats stats;
  EXPECT_THROW(DecodePacket(single, 0, calibration, want_last, &points, &stats), ParamError);
  // Not a data packet: counted, no points.
  std::string bad = packet;
  bad[100] = 0;
  EXPECT_FALSE(DecodePacket(bad, 0, calibration, {}, &points, &stats));
  EXPECT_EQ(stats.bad_packets, 1);
}

TEST(Pcap, RefusesWhatIsNotAClassicCapture) {
  const fs::path dir = locforge::testing::MakeTempDir("pcap_refusals");
  auto refused = [&](const std::string& bytes, const std::string& piece) {
    WriteFileAtomic(dir / "x.pcap", bytes);
    try {
      PcapReader reader(dir / "x.pcap");
      UdpPacket p;
      while (reader.Next(&p)) {
      }
      ADD_FAILURE() << "accepted; expected: " << piece;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(piece), std::string::npos) << e.what();
    }
  };
  refused(std::string("\x0a\x0d\x0d\x0a", 4) + std::string(40, '\0'), "editcap -F pcap");
  refused("hello", "shorter than a pcap file header");
  refused(std::string(24, 'x'), "not a pcap capture file");
  // A big-endian header whose record claims 1 GB.
  std::string header("\xa1\xb2\xc3\xd4\x00\x02\x00\x04", 8);
  header += std::string(8, '\0') + std::string("\x00\x00\xff\xff\x00\x00\x00\x01", 8);
  std::string record(16, '\0');
  record[8] = 0x40;  // captured length 0x40000000 (big endian)
  refused(header + record, "the file is corrupt");
  // The same header with a truncated last record: read to the end, counted.
  WriteFileAtomic(dir / "y.pcap", header + std::string(10, '\0'));
  PcapReader truncated(dir / "y.pcap");
  UdpPacket p;
  EXPECT_FALSE(truncated.Next(&p));
  EXPECT_EQ(truncated.stats().skipped, 1);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace locforge::velodyne

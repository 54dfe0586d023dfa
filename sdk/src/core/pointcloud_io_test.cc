// PLY/PCD round trips, the simulator's PCD layout, PCL-style headers, and
// errors naming the file.
#include "locforge/pointcloud_io.h"

#include <gtest/gtest.h>

#include <cstring>

#include "locforge/fs.h"
#include "testing.h"

namespace locforge {
namespace {

PointCloud MakeCloud(size_t n, bool normals, bool times) {
  PointCloud c;
  for (size_t i = 0; i < n; ++i) {
    const float f = static_cast<float>(i);
    c.points.emplace_back(0.1f * f, -2.5f + f, 1e-3f * f * f);
    if (normals) c.normals.push_back(Eigen::Vector3f(f, 1, 2).normalized());
    if (times) c.times.push_back(1700000000.123456 + 1e-6 * static_cast<double>(i));
  }
  return c;
}

void ExpectSame(const PointCloud& a, const PointCloud& b) {
  ASSERT_EQ(a.size(), b.size());
  ASSERT_EQ(a.normals.size(), b.normals.size());
  ASSERT_EQ(a.times.size(), b.times.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.points[i], b.points[i]) << i;
    if (a.has_normals()) EXPECT_EQ(a.normals[i], b.normals[i]) << i;
    if (a.has_times()) EXPECT_EQ(a.times[i], b.times[i]) << i;  // doubles kept exactly
  }
}

TEST(PointCloudIo, RoundTripsAllFormats) {
  const auto dir = testing::MakeTempDir("pcio");
  for (const bool normals : {false, true})
    for (const bool times : {false, true})
      for (const auto enc : {PointCloudEncoding::kAscii, PointCloudEncoding::kBinary})
        for (const char* ext : {".ply", ".pcd"}) {
          SCOPED_TRACE(std::string(ext) + (normals ? " normals" : "") + (times ? " times" : "") +
                       (enc == PointCloudEncoding::kAscii ? " ascii" : " binary"));
          const PointCloud c = MakeCloud(57, normals, times);
          PointAttributes attr;
          for (size_t i = 0; i < c.size(); ++i) {
            attr.intensity.push_back(0.5f * static_cast<float>(i));
            attr.ring.push_back(static_cast<uint16_t>(i % 32));
          }
          const auto file = dir / (std::string("c") + ext);
          WritePointCloud(file, c, enc, &attr);
          PointAttributes back_attr;
          ExpectSame(c, ReadPointCloud(file, &back_attr));
          EXPECT_EQ(back_attr.intensity, attr.intensity);
          EXPECT_EQ(back_attr.ring, attr.ring);
        }
  fs::remove_all(dir);
}

TEST(PointCloudIo, ReadsTheSimulatorPcdLayout) {
  // Same bytes as plugins/source/simulator/kapture_out.cc EncodePcd: packed
  // float x y z intensity, uint16 ring, double time (26 bytes a point).
  std::string bytes =
      "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
      "FIELDS x y z intensity ring time\nSIZE 4 4 4 4 2 8\nTYPE F F F F U F\nCOUNT 1 1 1 1 1 1\n"
      "WIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA binary\n";
  for (int i = 0; i < 2; ++i) {
    const float xyzi[4] = {1.f + i, 2.f, 3.f, 40.f + i};
    const uint16_t ring = static_cast<uint16_t>(7 + i);
    const double time = 12.5 + i;
    bytes.append(reinterpret_cast<const char*>(xyzi), 16);
    bytes.append(reinterpret_cast<const char*>(&ring), 2);
    bytes.append(reinterpret_cast<const char*>(&time), 8);
  }
  PointAttributes attr;
  const PointCloud c = DecodePcd(bytes, "scan.pcd", &attr);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.points[1], Eigen::Vector3f(2, 2, 3));
  EXPECT_EQ(c.times, (std::vector<double>{12.5, 13.5}));
  EXPECT_EQ(attr.ring, (std::vector<uint16_t>{7, 8}));
  EXPECT_EQ(attr.intensity, (std::vector<float>{40, 41}));
  // And our writer produces exactly that layout.
  const std::string ours = EncodePcd(c, PointCloudEncoding::kBinary, &attr);
  EXPECT_EQ(ours.substr(ours.find("FIELDS")), bytes.substr(bytes.find("FIELDS")));
}

TEST(PointCloudIo, ReadsPclAsciiPcdWithPaddingAndCounts) {
  // PCL writes an unused padding field "_" and multi-count fields.
  const std::string bytes =
      "# .PCD v.7\nVERSION .7\nFIELDS x y z _ normal_x normal_y normal_z curvature hist\n"
      "SIZE 4 4 4 1 4 4 4 4 4\nTYPE F F F U F F F F F\nCOUNT 1 1 1 1 1 1 1 1 3\n"
      "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n"
      "1 2 3 0 0 0 1 0.1 9 9 9\n4 5 6 0 0 1 0 0.2 8 8 8\n";
  const PointCloud c = DecodePcd(bytes, "pcl.pcd");
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.points[1], Eigen::Vector3f(4, 5, 6));
  EXPECT_EQ(c.normals[1], Eigen::Vector3f(0, 1, 0));
}

TEST(PointCloudIo, ReadsCloudComparePlyWithOtherElements) {
  std::string bytes =
      "ply\nformat binary_little_endian 1.0\ncomment x\nelement vertex 2\nproperty float x\n"
      "property float y\nproperty float z\nproperty float scalar_intensity\n"
      "element face 0\nproperty list uchar int vertex_indices\nend_header\n";
  const float v[8] = {1, 2, 3, 0.5f, 4, 5, 6, 0.25f};
  bytes.append(reinterpret_cast<const char*>(v), sizeof(v));
  PointAttributes attr;
  const PointCloud c = DecodePly(bytes, "cc.ply", &attr);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.points[1], Eigen::Vector3f(4, 5, 6));
  EXPECT_EQ(attr.intensity[1], 0.25f);
  EXPECT_FALSE(c.has_normals());
}

void ExpectInputError(const std::function<void()>& f, const std::vector<std::string>& parts) {
  try {
    f();
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    for (const auto& p : parts)
      EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what() << " lacks " << p;
  }
}

TEST(PointCloudIo, TruncatedAndMalformedFilesNameFileAndField) {
  const auto dir = testing::MakeTempDir("pcio");
  const PointCloud c = MakeCloud(10, true, true);
  for (const char* name : {"t.ply", "t.pcd"})
    for (const auto enc : {PointCloudEncoding::kAscii, PointCloudEncoding::kBinary}) {
      const auto file = dir / name;
      WritePointCloud(file, c, enc);
      std::string bytes = ReadFile(file);
      bytes.resize(bytes.size() - 30);
      WriteFileAtomic(file, bytes);
      ExpectInputError([&] { ReadPointCloud(file); }, {file.string(), "truncated"});
    }
  ExpectInputError([] { DecodePly("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                                  "property float y\nproperty float z\nend_header\n1 2 oops\n",
                                  "bad.ply"); },
                   {"bad.ply:8", "field 'z'", "expected a number"});
  ExpectInputError([] { DecodePly("ply\nformat binary_big_endian 1.0\nend_header\n", "be.ply"); },
                   {"be.ply:2", "format"});
  ExpectInputError([] { DecodePcd("FIELDS x y\nSIZE 4 4\nTYPE F F\nPOINTS 0\nDATA ascii\n", "xy.pcd"); },
                   {"xy.pcd", "field 'z'", "missing"});
  ExpectInputError([] { DecodePcd("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\n"
                                  "DATA binary_compressed\n", "z.pcd"); },
                   {"z.pcd:5", "DATA", "binary_compressed"});
  ExpectInputError([] { DecodePcd("FIELDS x y z\nSIZE 4 4\nTYPE F F F\nDATA ascii\n", "s.pcd"); },
                   {"s.pcd:1", "SIZE"});
  ExpectInputError([&] { ReadPointCloud(dir / "cloud.xyz"); }, {"cloud.xyz", "extension"});
  fs::remove_all(dir);
}

TEST(PointCloudIo, ReadsTheSharedRegistrationPair) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, "data/registration/small_gicp_pair");
  PointAttributes attr;
  const PointCloud source = ReadPly(dir / "source.ply", &attr);
  EXPECT_EQ(source.size(), 69792u);
  EXPECT_EQ(attr.intensity.size(), source.size());
  EXPECT_EQ(ReadPly(dir / "target.ply").size(), 69088u);
}

}  // namespace
}  // namespace locforge

// CopyKapture on every shared sample: binary files byte for byte, text
// files parsed on both sides and compared value by value, and the toolbox's
// formatting reproduced where the source was written by the toolbox.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <sstream>

#include "locforge/error.h"
#include "locforge/kapture/kapture.h"
#include "testing.h"

namespace locforge::kapture {
namespace {

std::string Slurp(const fs::path& p) { return ReadFile(p); }

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(a)) == 0; }

void ExpectSamePose(const Pose& a, const Pose& b, const std::string& where) {
  for (int i = 0; i < 4; ++i)
    EXPECT_TRUE(SameBits(a.q.coeffs()[i], b.q.coeffs()[i])) << where;
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(SameBits(a.t[i], b.t[i])) << where;
}

// Data lines of a text file (comments and blank lines dropped, CR removed).
std::vector<std::string> DataLines(const fs::path& p) {
  std::istringstream in(Slurp(p));
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    lines.push_back(line);
  }
  return lines;
}

template <class Record, class Eq>
void CompareRecords(const fs::path& a, const fs::path& b, Eq eq) {
  RecordsReader<Record> ra(a), rb(b);
  Record x, y;
  int64_t n = 0;
  while (true) {
    const bool more_a = ra.Next(&x), more_b = rb.Next(&y);
    ASSERT_EQ(more_a, more_b) << a << " record " << n;
    if (!more_a) break;
    EXPECT_TRUE(eq(x, y)) << a << " record " << n;
    ++n;
  }
  EXPECT_GT(n, 0) << a;
}

void CompareTextFile(const fs::path& src_root, const fs::path& dst_root, const std::string& rel) {
  const fs::path a = src_root / rel, b = dst_root / rel;
  SCOPED_TRACE(rel);
  ASSERT_TRUE(fs::exists(b));
  // Line for line: same number of data lines.
  EXPECT_EQ(DataLines(a).size(), DataLines(b).size());
  EXPECT_EQ(Slurp(b).rfind(kKaptureVersionHeader, 0), 0u) << "header line";
  const std::string name = fs::path(rel).filename().string();
  if (name == "sensors.txt") {
    const Sensors x = ReadSensors(a), y = ReadSensors(b);
    ASSERT_EQ(x.size(), y.size());
    for (size_t i = 0; i < x.size(); ++i) {
      EXPECT_EQ(x.list()[i].id, y.list()[i].id);
      EXPECT_EQ(x.list()[i].name, y.list()[i].name);
      EXPECT_EQ(x.list()[i].type, y.list()[i].type);
      EXPECT_EQ(x.list()[i].params, y.list()[i].params);
    }
  } else if (name == "rigs.txt") {
    const Rigs x = ReadRigs(a), y = ReadRigs(b);
    ASSERT_EQ(x.NumSensorEntries(), y.NumSensorEntries());
    for (const Rig& rig : x.list())
      for (const RigSensor& s : rig.sensors) {
        const RigSensor* t = y.Find(rig.id) ? y.Find(rig.id)->Find(s.sensor_id) : nullptr;
        ASSERT_TRUE(t) << rig.id << "/" << s.sensor_id;
        ExpectSamePose(s.sensor_from_rig, t->sensor_from_rig, s.sensor_id);
        EXPECT_EQ(s.parts, t->parts);
      }
  } else if (name == "trajectories.txt") {
    const Trajectories x = ReadTrajectories(a), y = ReadTrajectories(b);
    ASSERT_EQ(x.size(), y.size());
    for (const auto& [key, pose] : x.poses) {
      ASSERT_TRUE(y.Find(key.first, key.second));
      ExpectSamePose(pose, *y.Find(key.first, key.second), key.second);
    }
    EXPECT_EQ(x.partial, y.partial);
  } else if (name.rfind("records_", 0) == 0) {
    const std::string type = name.substr(8, name.size() - 12);
    switch (RecordKindOf(type)) {
      case RecordKind::kCamera:
      case RecordKind::kLidar:
      case RecordKind::kDepth:
        CompareRecords<DataRecord>(a, b, [](const DataRecord& p, const DataRecord& q) {
          return p.timestamp == q.timestamp && p.device_id == q.device_id && p.path == q.path;
        });
        break;
      case RecordKind::kGnss:
        CompareRecords<GnssRecord>(a, b, [](const GnssRecord& p, const GnssRecord& q) {
          return p.timestamp == q.timestamp && p.device_id == q.device_id && SameBits(p.x, q.x) &&
                 SameBits(p.y, q.y) && SameBits(p.z, q.z) && p.utc == q.utc &&
                 SameBits(p.dop, q.dop);
        });
        break;
      case RecordKind::kWifi:
        CompareRecords<WifiRecord>(a, b, [](const WifiRecord& p, const WifiRecord& q) {
          return p.timestamp == q.timestamp && p.device_id == q.device_id && p.bssid == q.bssid &&
                 p.frequency == q.frequency && SameBits(p.rssi, q.rssi) && p.ssid == q.ssid &&
                 p.scan_time_start == q.scan_time_start && p.scan_time_end == q.scan_time_end;
        });
        break;
      case RecordKind::kBluetooth:
        CompareRecords<BluetoothRecord>(a, b, [](const BluetoothRecord& p, const BluetoothRecord& q) {
          return p.timestamp == q.timestamp && p.device_id == q.device_id &&
                 p.address == q.address && SameBits(p.rssi, q.rssi) && p.name == q.name;
        });
        break;
      default:
        CompareRecords<GenericRecord>(a, b, [](const GenericRecord& p, const GenericRecord& q) {
          return p.timestamp == q.timestamp && p.device_id == q.device_id && p.values == q.values;
        });
    }
  } else if (name == "points3d.txt") {
    const auto x = ReadPoints3d(a), y = ReadPoints3d(b);
    ASSERT_EQ(x.size(), y.size());
    for (size_t i = 0; i < x.size(); ++i) {
      EXPECT_TRUE(SameBits(x[i].x, y[i].x) && SameBits(x[i].y, y[i].y) && SameBits(x[i].z, y[i].z));
      EXPECT_TRUE(SameBits(x[i].r, y[i].r) && SameBits(x[i].g, y[i].g) && SameBits(x[i].b, y[i].b));
    }
    // numpy.savetxt's "%.18e" reproduces the toolbox's file exactly.
    EXPECT_EQ(DataLines(a), DataLines(b));
  } else if (name == "observations.txt") {
    const auto x = ReadObservations(a), y = ReadObservations(b);
    ASSERT_EQ(x.size(), y.size());
    for (size_t i = 0; i < x.size(); ++i) {
      EXPECT_EQ(x[i].point3d_id, y[i].point3d_id);
      EXPECT_EQ(x[i].keypoints_type, y[i].keypoints_type);
      EXPECT_EQ(x[i].features, y[i].features);
    }
    EXPECT_EQ(DataLines(a), DataLines(b));
  } else if (name == "keypoints.txt" || name == "descriptors.txt" ||
             name == "global_features.txt") {
    const FeatureKind kind = name == "keypoints.txt" ? FeatureKind::kKeypoints
                             : name == "descriptors.txt" ? FeatureKind::kDescriptors
                                                         : FeatureKind::kGlobalFeatures;
    const FeatureInfo x = ReadFeatureInfo(a, kind), y = ReadFeatureInfo(b, kind);
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.dtype_name, y.dtype_name);
    EXPECT_EQ(x.dsize, y.dsize);
    EXPECT_EQ(x.keypoints_type, y.keypoints_type);
    EXPECT_EQ(x.metric_type, y.metric_type);
    EXPECT_EQ(DataLines(a), DataLines(b));
  } else {
    ADD_FAILURE() << "unexpected text file " << rel;
  }
}

struct TreeStats {
  int text = 0, binary = 0;
};

// Every file of src is in dst: text files compared by value, others byte
// for byte.
TreeStats CompareTrees(const fs::path& src, const fs::path& dst) {
  TreeStats stats;
  for (auto it = fs::recursive_directory_iterator(src); it != fs::recursive_directory_iterator();
       ++it) {
    if (!it->is_regular_file()) continue;
    const std::string rel = it->path().lexically_relative(src).generic_string();
    const bool kapture_text = it->path().extension() == ".txt" &&
                              rel.find("records_data/") == std::string::npos;
    if (kapture_text) {
      CompareTextFile(src, dst, rel);
      ++stats.text;
    } else {
      EXPECT_TRUE(fs::exists(dst / rel)) << rel;
      if (fs::exists(dst / rel)) EXPECT_TRUE(Slurp(it->path()) == Slurp(dst / rel)) << rel;
      ++stats.binary;
    }
  }
  // And nothing more in dst.
  int dst_files = 0;
  for (auto it = fs::recursive_directory_iterator(dst); it != fs::recursive_directory_iterator();
       ++it)
    dst_files += it->is_regular_file();
  EXPECT_EQ(dst_files, stats.text + stats.binary);
  return stats;
}

class CopySample : public ::testing::TestWithParam<const char*> {};

TEST_P(CopySample, ReproducesEveryFile) {
  LOCFORGE_SHARED_PATH_OR_SKIP(src, std::string("data/kapture/") + GetParam());
  const fs::path dst = locforge::testing::MakeTempDir("kapture_copy") / "out";
  const CopyReport report = CopyKapture(src, dst);
  // Only licence files are not kapture files; they are copied verbatim.
  for (const std::string& note : report.notes)
    if (note.rfind("copied verbatim", 0) == 0)
      EXPECT_NE(note.find("LICENSE"), std::string::npos) << note;
  const TreeStats stats = CompareTrees(src, dst);
  EXPECT_EQ(stats.text, report.text_files);
  EXPECT_EQ(stats.binary, report.binary_files + report.data_files + report.other_files);
  // The copy is itself a valid kapture with the same summary.
  const KaptureSummary a = InspectKapture(src), b = InspectKapture(dst);
  EXPECT_EQ(FormatSummary(a).substr(FormatSummary(a).find('\n')),
            FormatSummary(b).substr(FormatSummary(b).find('\n')));
  fs::remove_all(dst.parent_path());
}

INSTANTIATE_TEST_SUITE_P(
    Samples, CopySample,
    ::testing::Values("maupertuis/kapture", "7scenes_stairs/mapping", "7scenes_stairs/query",
                      "m1x_metadata", "virtual_gallery_metadata/all",
                      "virtual_gallery_metadata/reduced", "virtual_gallery_metadata/testing",
                      "virtual_gallery_metadata/training", "virtual_gallery_tutorial/mapping",
                      "virtual_gallery_tutorial/query"),
    [](const ::testing::TestParamInfo<const char*>& info) {
      std::string name = info.param;
      for (char& c : name)
        if (!isalnum(static_cast<unsigned char>(c))) c = '_';
      return name;
    });

TEST(CopyFeatureFolder, VirtualGalleryTutorialFeatures) {
  LOCFORGE_SHARED_PATH_OR_SKIP(tutorial, "data/kapture/virtual_gallery_tutorial");
  const fs::path tmp = locforge::testing::MakeTempDir("kapture_features");
  const struct {
    FeatureKind kind;
    const char* dir;
    int files;
  } folders[] = {
      {FeatureKind::kKeypoints, "local_features/r2d2_500/keypoints", 16},
      {FeatureKind::kDescriptors, "local_features/r2d2_500/descriptors", 16},
      {FeatureKind::kGlobalFeatures, "global_features/AP-GeM-LM18/global_features", 16},
  };
  for (const auto& f : folders) {
    SCOPED_TRACE(f.dir);
    EXPECT_EQ(CopyFeatureFolder(f.kind, tutorial / f.dir, tmp / f.dir), f.files);
    const TreeStats stats = CompareTrees(tutorial / f.dir, tmp / f.dir);
    EXPECT_EQ(stats.text, 1);
    EXPECT_EQ(stats.binary, f.files);
  }
  fs::remove_all(tmp);
}

TEST(CopyFormatting, ToolboxWrittenFilesAreReproducedByteForByte) {
  // Files the toolbox wrote (Python repr floats, padded timestamps) come out
  // identical, not only equal in value.
  LOCFORGE_SHARED_PATH_OR_SKIP(m1x, "data/kapture/m1x_metadata");
  LOCFORGE_SHARED_PATH_OR_SKIP(seven, "data/kapture/7scenes_stairs/mapping");
  LOCFORGE_SHARED_PATH_OR_SKIP(vg, "data/kapture/virtual_gallery_metadata/all");
  const fs::path tmp = locforge::testing::MakeTempDir("kapture_fmt");
  CopyKapture(m1x, tmp / "m1x");
  CopyKapture(seven, tmp / "seven");
  CopyKapture(vg, tmp / "vg");
  for (const char* rel : {"sensors/trajectories.txt", "sensors/rigs.txt", "sensors/sensors.txt",
                          "sensors/records_camera.txt", "sensors/records_lidar.txt"})
    EXPECT_EQ(DataLines(m1x / rel), DataLines(tmp / "m1x" / rel)) << rel;
  for (const char* rel : {"sensors/trajectories.txt", "sensors/records_depth.txt"})
    EXPECT_EQ(DataLines(seven / rel), DataLines(tmp / "seven" / rel)) << rel;
  EXPECT_EQ(DataLines(vg / "sensors/trajectories.txt"),
            DataLines(tmp / "vg" / "sensors/trajectories.txt"));
  fs::remove_all(tmp);
}

TEST(CopyKapture, RefusesToWriteIntoTheSource) {
  LOCFORGE_SHARED_PATH_OR_SKIP(src, "data/kapture/m1x_metadata");
  // Work on a writable copy so the refusal, not permissions, is what stops it.
  const fs::path tmp = locforge::testing::MakeTempDir("kapture_self");
  CopyKapture(src, tmp / "a");
  EXPECT_THROW(CopyKapture(tmp / "a", tmp / "a"), InputError);
  EXPECT_THROW(CopyKapture(tmp / "a", tmp / "a" / "sensors" / "x"), InputError);
  EXPECT_THROW(CopyKapture(tmp / "a" / "sensors", tmp), InputError);
  try {
    CopyKapture(tmp / "a", tmp / "a/./");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("refusing"), std::string::npos);
  }
  // Non-empty destination: refused unless overwrite.
  CopyKapture(src, tmp / "b");
  EXPECT_THROW(CopyKapture(src, tmp / "b"), InputError);
  CopyOptions overwrite;
  overwrite.overwrite = true;
  EXPECT_NO_THROW(CopyKapture(src, tmp / "b", overwrite));
  fs::remove_all(tmp);
}

}  // namespace
}  // namespace locforge::kapture

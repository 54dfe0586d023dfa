// The part file of slam/sequences (slam_part.h): a byte-identical round
// trip, and malformed files refused naming the file and the field.
#include "slam_part.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include "locforge/error.h"

namespace locforge::lidar {
namespace {

SlamPart SamplePart() {
  SlamPart part;
  part.sequence = "map_01";
  part.manual = true;
  part.params = {{"keyframe_distance_m", "0.5"}, {"registration", "registration/gicp"}};
  for (int i = 0; i < 3; ++i) {
    Keyframe kf;
    kf.id = i;
    kf.sequence = part.sequence;
    kf.timestamp = 1000000 + 250000 * i;
    kf.travelled = 0.1 * i + 1e-17;
    for (int p = 0; p < 5 + i; ++p) kf.cloud.points.emplace_back(0.1f * p, -0.3f * i, 1.0f / 3);
    kf.rough.points.emplace_back(0.25f, 0.5f, 0.75f);
    if (i == 1) kf.rough.normals.emplace_back(0, 0, 1);
    part.keyframes.push_back(kf);
    part.graph.nodes[i] = Pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * i, Eigen::Vector3d::UnitZ())),
                               Eigen::Vector3d(i, 2.0 / 3, 0));
    part.before.nodes[i] = Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(i * 1.01, 0, 0));
  }
  PoseGraphEdge e;
  e.from = 0;
  e.to = 2;
  e.T_from_to = part.graph.nodes[2];
  e.information = Matrix6d::Identity() * 1e4;
  e.information(0, 5) = e.information(5, 0) = 3.5;
  e.loss = RobustLoss::kCauchy;
  e.loss_scale = 1.5;
  e.loop = true;
  part.graph.edges = {e, e};
  part.graph.edges[1].from = 1;
  part.graph.edges[1].loop = false;
  part.loops = {{0, 2}};
  part.stats.sequential_fallbacks = 1;
  part.stats.refinements = 7;
  part.stats.loop_tests = 1234567890123;
  part.stats.odometry_yaw_scale = {{"map_01", 1.0123}};
  part.stats.summary.initial_cost = 25100.4;
  part.stats.summary.final_cost = 3.7;
  part.stats.summary.iterations = 12;
  part.stats.steps = {{"keyframes", 0.5}, {"sequential edges", 2.25}};
  return part;
}

TEST(SlamPart, RoundTripIsByteIdenticalAndKeepsEveryValue) {
  const SlamPart part = SamplePart();
  const std::string bytes = EncodeSlamPart(part);
  const SlamPart back = DecodeSlamPart(bytes, "map_01.part");
  EXPECT_EQ(EncodeSlamPart(back), bytes);
  EXPECT_EQ(back.sequence, "map_01");
  EXPECT_TRUE(back.manual);
  EXPECT_EQ(back.params, part.params);
  ASSERT_EQ(back.keyframes.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(back.keyframes[i].id, static_cast<int>(i));
    EXPECT_EQ(back.keyframes[i].sequence, "map_01");
    EXPECT_EQ(back.keyframes[i].timestamp, part.keyframes[i].timestamp);
    EXPECT_EQ(back.keyframes[i].travelled, part.keyframes[i].travelled);
    EXPECT_EQ(back.keyframes[i].cloud.points, part.keyframes[i].cloud.points);
    EXPECT_EQ(back.keyframes[i].rough.normals, part.keyframes[i].rough.normals);
    EXPECT_EQ(back.graph.nodes.at(i).q.coeffs(), part.graph.nodes.at(i).q.coeffs());
    EXPECT_EQ(back.graph.nodes.at(i).t, part.graph.nodes.at(i).t);
    EXPECT_EQ(back.before.nodes.at(i).t, part.before.nodes.at(i).t);
  }
  ASSERT_EQ(back.graph.edges.size(), 2u);
  EXPECT_EQ(back.graph.edges[0].information, part.graph.edges[0].information);
  EXPECT_EQ(back.graph.edges[0].loss, RobustLoss::kCauchy);
  EXPECT_TRUE(back.graph.edges[0].loop);
  EXPECT_EQ(back.graph.edges[1].from, 1);
  EXPECT_FALSE(back.graph.edges[1].loop);
  EXPECT_EQ(back.loops, part.loops);
  EXPECT_EQ(back.stats.loop_tests, part.stats.loop_tests);
  EXPECT_EQ(back.stats.odometry_yaw_scale, part.stats.odometry_yaw_scale);
  EXPECT_EQ(back.stats.steps, part.stats.steps);
  EXPECT_EQ(back.stats.summary.iterations, 12);
}

// Read without its clouds (the join over many parts), a part names where
// each cloud is, and reading it from there gives the same cloud back.
TEST(SlamPart, CloudsLeftInTheFileAreReadBackTheSame) {
  const fs::path dir = fs::temp_directory_path() / ("slam_part_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const SlamPart part = SamplePart();
  WriteSlamPart(dir / "map_01.part", part);
  const SlamPart in_memory = ReadSlamPart(dir / "map_01.part");
  const SlamPart on_disk = ReadSlamPart(dir / "map_01.part", false);
  ASSERT_EQ(on_disk.keyframes.size(), part.keyframes.size());
  for (size_t i = 0; i < part.keyframes.size(); ++i) {
    const Keyframe& kf = on_disk.keyframes[i];
    EXPECT_TRUE(kf.cloud.empty());
    EXPECT_EQ(kf.cloud_file, dir / "map_01.part");
    EXPECT_EQ(kf.context.grid, in_memory.keyframes[i].context.grid);
    EXPECT_EQ(kf.rough.points, part.keyframes[i].rough.points);
    const Cloud c = ReadPartCloud(kf.cloud_file, kf.cloud_offset);
    EXPECT_EQ(c.points, part.keyframes[i].cloud.points) << i;
    EXPECT_EQ(c.normals, part.keyframes[i].cloud.normals) << i;
  }
  // A file cut short after it was read: the cloud's read names the file and field.
  const std::string bytes = ReadFile(dir / "map_01.part");
  WriteFileAtomic(dir / "map_01.part", bytes.substr(0, on_disk.keyframes[2].cloud_offset + 20));
  try {
    ReadPartCloud(dir / "map_01.part", on_disk.keyframes[2].cloud_offset);
    ADD_FAILURE() << "a truncated cloud was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'keyframes.cloud'"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

void ExpectRefused(const std::string& bytes, const std::string& field) {
  try {
    DecodeSlamPart(bytes, "parts/map_01.part");
    ADD_FAILURE() << "accepted; expected a refusal naming " << field;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("parts/map_01.part"), std::string::npos) << what;
    EXPECT_NE(what.find("'" + field + "'"), std::string::npos) << what;
  }
}

TEST(SlamPart, MalformedFilesAreRefusedNamingTheField) {
  const std::string bytes = EncodeSlamPart(SamplePart());
  ExpectRefused("a text file", "magic");
  std::string version = bytes;
  version[10] = 9;  // the u32 after the 10-byte magic
  ExpectRefused(version, "version");
  // Every truncation is refused (never read past the end), naming some field.
  for (size_t n = 0; n < bytes.size(); n += 7) EXPECT_THROW(DecodeSlamPart(bytes.substr(0, n), "p"), InputError) << n;
  ExpectRefused(bytes + "x", "end");
  // An edge to a keyframe the part does not have.
  SlamPart bad = SamplePart();
  bad.graph.edges[0].to = 3;
  ExpectRefused(EncodeSlamPart(bad), "edges.to");
  SlamPart empty = SamplePart();
  empty.keyframes.clear();
  empty.graph.nodes.clear();
  empty.before.nodes.clear();
  empty.graph.edges.clear();
  empty.loops.clear();
  ExpectRefused(EncodeSlamPart(empty), "keyframes");
}

}  // namespace
}  // namespace locforge::lidar

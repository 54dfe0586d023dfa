// Text files the toolbox writes in more than one form: points3d.txt with or
// without colours, poses with neither rotation nor translation, and the
// toolbox's column paddings.
#include "locforge/kapture/io.h"

#include <gtest/gtest.h>

#include <functional>
#include <sstream>

#include "locforge/error.h"
#include "testing.h"

namespace locforge::kapture {
namespace {

std::string InputErrorOf(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Points3d, ReadsXyzOnlyAndWritesItBackWithoutColours) {
  std::istringstream in("# kapture format: 1.1\n# X, Y, Z\n1.0,2.0,3.0\n4,5,6\n");
  const auto points = ParsePoints3d(in, "points3d.txt");
  ASSERT_EQ(points.size(), 2u);
  EXPECT_FALSE(points[1].has_color);
  EXPECT_EQ(points[1].z, 6.0);
  const fs::path tmp = locforge::testing::MakeTempDir("points3d");
  WritePoints3d(tmp / "p.txt", points);
  EXPECT_EQ(ReadFile(tmp / "p.txt"),
            "# kapture format: 1.1\n# X, Y, Z\n"
            "1.000000000000000000e+00,2.000000000000000000e+00,3.000000000000000000e+00\n"
            "4.000000000000000000e+00,5.000000000000000000e+00,6.000000000000000000e+00\n");
  // With colours (the default of a Point3d), the six columns.
  WritePoints3d(tmp / "c.txt", {{1, 2, 3, 255, 128, 0}});
  EXPECT_NE(ReadFile(tmp / "c.txt").find("# X, Y, Z, R, G, B\n"), std::string::npos);
  EXPECT_TRUE(ReadPoints3d(tmp / "c.txt")[0].has_color);
  fs::remove_all(tmp);
}

TEST(Points3d, WithoutAHeaderTheFirstLineTellsAndEveryLineMustAgree) {
  std::istringstream xyz("1,2,3\n4,5,6\n");
  EXPECT_FALSE(ParsePoints3d(xyz, "p.txt")[0].has_color);
  std::istringstream mixed("1,2,3\n4,5,6,7,8,9\n");
  EXPECT_EQ(InputErrorOf([&] { ParsePoints3d(mixed, "p.txt"); }),
            "p.txt:2: expected 3 fields (X, Y, Z), got 6");
  std::istringstream header("# kapture format: 1.1\n# X, Y, Z, R, G, B\n1,2,3\n");
  EXPECT_EQ(InputErrorOf([&] { ParsePoints3d(header, "p.txt"); }),
            "p.txt:3: expected 6 fields (X, Y, Z, R, G, B), got 3");
  std::istringstream four("1,2,3,4\n");
  EXPECT_NE(InputErrorOf([&] { ParsePoints3d(four, "p.txt"); }), "");
}

TEST(Poses, AllSevenFieldsEmptyIsTheIdentityWithNeitherPart) {
  std::istringstream in(
      "# kapture format: 1.1\n"
      " rig0,   001,     ,     ,     ,     ,     ,     ,     \n");
  const Rigs rigs = ParseRigs(in, "rigs.txt");
  const RigSensor& s = rigs.list().at(0).sensors.at(0);
  EXPECT_EQ(s.parts, PoseParts::kNone);
  EXPECT_EQ(s.sensor_from_rig.q.coeffs(), Eigen::Quaterniond::Identity().coeffs());
  EXPECT_EQ(s.sensor_from_rig.t, Eigen::Vector3d::Zero());
  const fs::path tmp = locforge::testing::MakeTempDir("poses");
  WriteRigs(tmp / "rigs.txt", rigs);
  // The toolbox's writer: ids right-aligned to 3, empty pose fields to 4.
  EXPECT_EQ(ReadFile(tmp / "rigs.txt"),
            "# kapture format: 1.1\n# rig_id, sensor_id, qw, qx, qy, qz, tx, ty, tz\n"
            "rig0, 001,     ,     ,     ,     ,     ,     ,     \n");
  fs::remove_all(tmp);
}

TEST(Poses, TrajectoriesKeepEmptyAndPartialPosesAndTheToolboxPaddings) {
  std::istringstream in(
      "0, 0, , , , , , , \n"
      "1, 0, 1.0, 0.0, 0.0, 0.0, , , \n"
      "2, 0, , , , , 0.0, 1.5, -2.0\n");
  const Trajectories t = ParseTrajectories(in, "trajectories.txt");
  EXPECT_EQ(t.PartsOf({0, "0"}), PoseParts::kNone);
  EXPECT_EQ(t.PartsOf({1, "0"}), PoseParts::kRotationOnly);
  EXPECT_EQ(t.PartsOf({2, "0"}), PoseParts::kTranslationOnly);
  const fs::path tmp = locforge::testing::MakeTempDir("poses");
  WriteTrajectories(tmp / "t.txt", t);
  EXPECT_EQ(ReadFile(tmp / "t.txt"),
            "# kapture format: 1.1\n# timestamp, device_id, qw, qx, qy, qz, tx, ty, tz\n"
            "       0,   0,     ,     ,     ,     ,     ,     ,     \n"
            "       1,   0, 1.0, 0.0, 0.0, 0.0,     ,     ,     \n"
            "       2,   0,     ,     ,     ,     , 0.0, 1.5, -2.0\n");
  EXPECT_EQ(ReadTrajectories(tmp / "t.txt").partial, t.partial);
  fs::remove_all(tmp);
  // A part half empty is still refused, naming the field.
  std::istringstream half("0, 0, 1.0, , 0.0, 0.0, 0, 0, 0\n");
  EXPECT_EQ(InputErrorOf([&] { ParseTrajectories(half, "trajectories.txt"); }),
            "trajectories.txt:1: field 'qx': empty while other fields of the rotation are set");
}

}  // namespace
}  // namespace locforge::kapture

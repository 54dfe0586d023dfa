#include "floor_grid.h"

#include <gtest/gtest.h>

#include <cmath>

#include "scan_context.h"
#include "synthetic_floor.h"

namespace locforge::lidar {
namespace {

Pose Yaw(double yaw_deg, double x = 0, double y = 0) {
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitZ())),
              Eigen::Vector3d(x, y, 0));
}

FloorGrid GridOf(const std::vector<Segment>& walls, const std::vector<Pose>& poses_in_frame,
                 const Pose& T_world_frame) {
  Eigen::AlignedBox2d box;
  for (const Pose& p : poses_in_frame) {
    box.extend(p.t.head<2>() - Eigen::Vector2d::Constant(31));
    box.extend(p.t.head<2>() + Eigen::Vector2d::Constant(31));
  }
  FloorGrid grid(FloorGridOptions{}, box);
  for (const Pose& p : poses_in_frame) grid.AddScan(SimulateFloorScan(walls, T_world_frame * p), p);
  grid.Finish();
  return grid;
}

// An L-shaped corridor: 2 m wide along x from 0 to 20, then up along y at x = 20.
std::vector<Segment> LCorridor() {
  return {{{-1, -1}, {21, -1}}, {{-1, 1}, {19, 1}}, {{19, 1}, {19, 15}}, {{21, -1}, {21, 15}},
          {{-1, -1}, {-1, 1}}, {{19, 15}, {21, 15}}};
}

TEST(FloorGrid, ClassifiesWallsCorridorAndUnseenSpace) {
  const auto walls = LCorridor();
  std::vector<Pose> poses;
  for (double x = 0; x <= 18; x += 0.5) poses.push_back(Yaw(0, x, 0));
  const FloorGrid g = GridOf(walls, poses, Pose());
  EXPECT_EQ(g.At({5.05, 0.05}), FloorGrid::State::kFree);       // corridor middle
  EXPECT_EQ(g.At({5.05, 1.02}), FloorGrid::State::kOccupied);   // the wall
  EXPECT_EQ(g.At({5.05, 4.05}), FloorGrid::State::kUnknown);    // behind the wall
  EXPECT_EQ(g.At({500, 0}), FloorGrid::State::kUnknown);        // outside the grid
  EXPECT_TRUE(g.NearOccupied({5.05, 0.8}));                     // within the 0.3 m margin
  EXPECT_FALSE(g.NearOccupied({5.05, 0.0}));
  EXPECT_GT(g.structure().size(), 300u);                        // ~40 m of wall at 0.1 m
}

// Sequence B drives the vertical leg, its frame turned 90 deg and moved
// against A's (which drove the horizontal leg and looked into the corner).
TEST(FloorGrid, RightFrameAgreesAndWrongFramesConflict) {
  const auto walls = LCorridor();
  std::vector<Pose> pa, pb;
  for (double x = 0; x <= 20; x += 0.5) pa.push_back(Yaw(0, x, 0));
  const Pose T_world_b = Yaw(90, 20, 0);  // B's frame: origin at the corner, x up the vertical leg
  for (double s = 0; s <= 14; s += 0.5) pb.push_back(Yaw(0, s, 0));
  const FloorGrid a = GridOf(walls, pa, Pose());
  const FloorGrid b = GridOf(walls, pb, T_world_b);

  const JoinEvidence right = EvaluateJoin(a, b, T_world_b);
  EXPECT_GT(right.Agreeing(), 400);
  EXPECT_LT(right.Conflict(), 0.03);
  // The same place seen with B's frame not turned (its leg along A's
  // corridor), turned the other way, and slid 4 m: each puts walls into the
  // other's free space (a corridor's end, the corner), and agrees less.
  for (const Pose& wrong : {Yaw(0, 20, 0), Yaw(-90, 20, 0), Yaw(180, 20, 0), Yaw(90, 16, 0)}) {
    const JoinEvidence e = EvaluateJoin(a, b, wrong);
    EXPECT_GT(e.Conflict(), 2 * right.Conflict() + 0.04) << "yaw " << Eigen::AngleAxisd(wrong.q).angle() * 180 / M_PI
                                                         << " t " << wrong.t.transpose();
    EXPECT_LT(e.Agreeing(), right.Agreeing()) << wrong.t.transpose();
  }
}

TEST(FloorGrid, RefusesBadOptions) {
  FloorGridOptions o;
  o.cell_m = 0;
  EXPECT_FALSE(o.Check());
  o = {};
  o.max_height_m = o.min_height_m;
  EXPECT_FALSE(o.Check());
  EXPECT_THROW(FloorGrid(o, Eigen::AlignedBox2d(Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1))), Error);
}

TEST(ScanContext, RecoversTheHeadingBetweenTwoScansOfOnePlace) {
  // A room with an irregular outline, so no turn but the true one aligns it.
  const std::vector<Segment> room = {{{-4, -3}, {6, -3}}, {{6, -3}, {6, 2}}, {{6, 2}, {2, 5}}, {{2, 5}, {-4, 5}},
                                     {{-4, 5}, {-4, -3}}, {{1, -1}, {2, -1}}, {{-2, 2}, {-2, 3.5}}};
  ScanContextOptions o;
  const ScanContext a = MakeScanContext(SimulateFloorScan(room, Yaw(0, 0.2, 0.1)), o);
  for (double yaw : {37.0, -120.0, 175.0}) {
    // b at (nearly) the same place, turned by `yaw`: p_a = Rz(yaw) p_b.
    const ScanContext b = MakeScanContext(SimulateFloorScan(room, Yaw(yaw, 0.3, 0.1)), o);
    const ScanContextMatch m = CompareScanContexts(a, b);
    double err = std::remainder(m.yaw * 180 / M_PI - yaw, 360.0);
    EXPECT_LT(std::abs(err), 6.1) << yaw;  // one sector
    EXPECT_LT(m.distance, 0.15);
    EXPECT_LT(RingKeyDistance(a, b), 0.05);
  }
  // Another place of the room scores worse.
  const ScanContext far = MakeScanContext(SimulateFloorScan(room, Yaw(0, 4.5, -1.5)), o);
  EXPECT_GT(CompareScanContexts(a, far).distance, 0.15);
}

}  // namespace
}  // namespace locforge::lidar

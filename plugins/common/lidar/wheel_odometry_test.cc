#include "wheel_odometry.h"

#include <gtest/gtest.h>

#include <cmath>

#include "locforge/error.h"

namespace locforge::lidar {
namespace {

// Ticks of a platform driving an arc of radius R at speed v for `seconds`.
std::vector<WheelTicks> ArcTicks(const WheelParams& p, double v, double R, double seconds, Timestamp t0) {
  std::vector<WheelTicks> ticks;
  const double w = v / R;
  for (int i = 0; i <= seconds * 100; ++i) {
    const double t = i * 0.01;
    const double left = (v - w * p.axle / 2) * t, right = (v + w * p.axle / 2) * t;
    const double per_m = p.pulses_per_rev / (2 * M_PI * p.radius);
    ticks.push_back({t0 + static_cast<Timestamp>(i * 10000), std::llround(left * per_m), std::llround(right * per_m)});
  }
  return ticks;
}

TEST(WheelOdometry, IntegratesAnArcWithinQuantisation) {
  const WheelParams p{0.1, 0.5, 1024};
  const double v = 1.0, R = 5.0, T = 10;
  WheelOdometry odo(p, ArcTicks(p, v, R, T, 1000000));
  const double theta = v * T / R;
  const Eigen::Vector3d expected(R * std::sin(theta), R * (1 - std::cos(theta)), 0);
  const Pose end = odo.PlatformPose(1000000 + T * 1e6);
  EXPECT_LT((end.t - expected).norm(), 0.01 * v * T);  // < 1 % of distance (tick rounding)
  EXPECT_NEAR(Eigen::AngleAxisd(end.q).angle(), theta, 0.01);
  // Interpolation at mid-sample times and relative poses.
  const Pose mid = odo.PlatformPose(1000000 + 5.005e6);
  EXPECT_NEAR(mid.t.x(), R * std::sin(v * 5.005 / R), 0.02);
  const Pose rel = odo.Relative(1000000 + 2e6, 1000000 + 3e6);
  EXPECT_NEAR(rel.t.norm(), 2 * R * std::sin(0.5 * v / R), 0.01);
  EXPECT_NEAR(odo.Distance(1000000, 1000000 + 4e6), 4.0, 0.01);
}

TEST(WheelOdometry, GapsStartSegmentsAndRelativeAcrossThemIsRefused) {
  const WheelParams p{0.1, 0.5, 1024};
  auto a = ArcTicks(p, 0.5, 1e9, 2, 0);
  const auto b = ArcTicks(p, 0.5, 1e9, 2, 100000000);  // 100 s later, ticks restart at 0
  a.insert(a.end(), b.begin(), b.end());
  WheelOdometry odo(p, a);
  EXPECT_EQ(odo.num_segments(), 2u);
  EXPECT_TRUE(odo.SameSegment(0, 1.5e6));
  EXPECT_FALSE(odo.SameSegment(0, 100.5e6));
  EXPECT_THROW(odo.Relative(0, 100.5e6), Error);
  EXPECT_NEAR(odo.Relative(100e6, 101e6).t.x(), 0.5, 0.005);
  EXPECT_THROW(odo.PlatformPose(50e6), Error);
  EXPECT_THROW(WheelOdometry(WheelParams{0, 0.5, 1024}, a), ParamError);
}

}  // namespace
}  // namespace locforge::lidar

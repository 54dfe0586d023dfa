#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "platform.h"

namespace locforge::sim {
namespace {

Trajectory SquareLoop(double side, int laps) {
  std::vector<Eigen::Vector2d> wp;
  std::vector<bool> spins;
  for (int lap = 0; lap < laps; ++lap)
    for (const Eigen::Vector2d c : {Eigen::Vector2d(0, 0), Eigen::Vector2d(side, 0),
                                    Eigen::Vector2d(side, side), Eigen::Vector2d(0, side)}) {
      wp.push_back(c);
      spins.push_back(wp.size() == 3);
    }
  wp.push_back({0, 0});
  spins.push_back(false);
  return Drive(wp, spins, 0, MotionLimits{}, 1e9, 0.1);
}

TEST(Platform, DrivesTheRouteWithinTheMotionLimits) {
  const Trajectory t = SquareLoop(8, 1);
  const MotionLimits lim;
  double max_v = 0, max_w = 0;
  for (const auto& s : t.states) {
    max_v = std::max(max_v, std::abs(s.v));
    max_w = std::max(max_w, std::abs(s.w));
  }
  EXPECT_LE(max_v, lim.max_speed + 1e-9);
  EXPECT_GT(max_v, 0.95 * lim.max_speed);
  EXPECT_LE(max_w, lim.max_turn_rate + 1e-9);
  EXPECT_GT(max_w, 0.9 * lim.max_turn_rate);  // the spin is a rapid rotation
  const PlanarState end = t.states.back();
  EXPECT_NEAR(end.x, 0, 0.1);
  EXPECT_NEAR(end.y, 0, 0.1);
  EXPECT_GT(t.Distance(), 30);
  // Exact unicycle: advancing a state by dt lands on the next one.
  for (size_t i = 0; i + 1 < t.states.size(); i += 97) {
    const PlanarState a = Advance(t.states[i], t.dt), &b = t.states[i + 1];
    EXPECT_NEAR(a.x, b.x, 1e-12);
    EXPECT_NEAR(a.y, b.y, 1e-12);
  }
  // Poses: origin at the axle height, x forward.
  const Pose p = t.PoseAt(1.0);
  const PlanarState s = t.StateAt(1.0);
  EXPECT_NEAR(p.t.z(), 0.1, 1e-12);
  EXPECT_NEAR((p.R() * Eigen::Vector3d::UnitX() - Eigen::Vector3d(std::cos(s.yaw), std::sin(s.yaw), 0)).norm(), 0, 1e-12);
}

TEST(Platform, NoiselessEncodersIntegrateToTheTrueTrajectory) {
  const Trajectory t = SquareLoop(8, 2);
  WheelOptions w;
  w.scale_error = w.differential_error = w.slip_sigma = 0;
  const auto readings = SimulateEncoders(t, w, 1);
  ASSERT_NEAR(readings.size(), t.duration() * w.rate_hz, 2);
  const auto odo = IntegrateEncoders(readings, w, t.states.front());
  double worst = 0;
  for (const auto& o : odo) {
    const PlanarState truth = t.StateAt(o.t);
    worst = std::max(worst, std::hypot(o.x - truth.x, o.y - truth.y));
  }
  // Only quantisation remains: 1 pulse = 0.6 mm of wheel travel.
  EXPECT_LT(worst, 1e-3 * t.Distance());
  EXPECT_LT(std::abs(std::remainder(odo.back().yaw - t.states.back().yaw, 2 * M_PI)), 0.003);
}

TEST(Platform, DefaultEncoderNoiseDriftsOneToTwoPercent) {
  const Trajectory t = SquareLoop(10, 2);
  WheelOptions w;
  double sum = 0;
  const int seeds = 12;
  for (int seed = 0; seed < seeds; ++seed) {
    const auto odo = IntegrateEncoders(SimulateEncoders(t, w, seed), w, t.states.front());
    const PlanarState truth = t.StateAt(odo.back().t);
    sum += std::hypot(odo.back().x - truth.x, odo.back().y - truth.y) / t.Distance();
  }
  const double mean_drift = sum / seeds;
  std::printf("mean odometry drift over %.0f m: %.2f %% of distance\n", t.Distance(), 100 * mean_drift);
  EXPECT_GT(mean_drift, 0.003);
  EXPECT_LT(mean_drift, 0.03);
}

TEST(Platform, RoutesStayInTheirArea) {
  WalkGraph g;
  for (int i = 0; i < 5; ++i) g.nodes.emplace_back(i * 10, 0);
  for (int i = 0; i < 4; ++i) g.edges.emplace_back(i, i + 1);
  std::mt19937_64 rng(5);
  const auto route = PlanRoute(g, 2, 100, rng, [&](int n) { return g.nodes[n].x() >= 20; });
  EXPECT_GE(route.size(), 10u);
  for (int n : route) EXPECT_GE(g.nodes[n].x(), 20);
}

}  // namespace
}  // namespace locforge::sim

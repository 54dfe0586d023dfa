// The mapping platform: a differential drive (origin at the centre of the
// wheel axle, x forward, y left, z up), the trajectories it drives through the
// corridor graph, and its wheel encoders.
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_PLATFORM_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_PLATFORM_H_

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <random>
#include <vector>

#include "locforge/pose.h"
#include "scene.h"

namespace locforge::sim {

struct WheelOptions {
  double radius = 0.1;            // wheel radius (m); the platform origin is this high
  double axle = 0.5;              // distance between the wheels (m)
  int pulses_per_rev = 1024;      // encoder resolution
  double rate_hz = 100;           // encoder sampling rate
  double scale_error = 0.01;      // sigma of the common relative wheel-radius error, per sequence
  double differential_error = 2e-4;  // sigma of the relative left/right radius mismatch
  double slip_sigma = 1e-3;       // random slip per wheel, m per sqrt(m) travelled
  bool Check(std::string* why) const;
};

struct MotionLimits {
  double max_speed = 1.0;         // m/s
  double max_turn_rate = 1.5;     // rad/s (rapid rotations)
  double max_accel = 0.8;         // m/s^2
  double max_turn_accel = 4.0;    // rad/s^2
};

// Planar state; (v, w) is the command held from t to the next state.
struct PlanarState {
  double t = 0, x = 0, y = 0, yaw = 0, v = 0, w = 0;
};

// A trajectory sampled every dt with piecewise-constant (v, w): the state at
// any instant follows exactly from the unicycle model.
struct Trajectory {
  std::vector<PlanarState> states;
  double dt = 0.002;
  double height = 0.1;  // z of the platform origin (the wheel radius)

  double duration() const { return states.empty() ? 0 : states.back().t; }
  double Distance() const;
  PlanarState StateAt(double t) const;
  // Platform-to-world transform T_world_platform at time t.
  Pose PoseAt(double t) const;
};

// Advances (x, y, yaw) by a constant (v, w) over tau seconds (exact arc).
PlanarState Advance(const PlanarState& s, double tau);

// Drives through the waypoints from (waypoints[0], start_yaw): turn towards
// the next waypoint while driving (speed drops with the heading error), spin
// a full turn in place at waypoints flagged in `spins`, stop at the last one
// or after max_duration seconds.
Trajectory Drive(const std::vector<Eigen::Vector2d>& waypoints, const std::vector<bool>& spins,
                 double start_yaw, const MotionLimits& limits, double max_duration,
                 double height, double dt = 0.002);

// A random walk on the graph from `start_node`, restricted to nodes accepted by
// `allowed` (when set), of at least `length_m` metres. Never turns straight back
// unless at a dead end.
std::vector<int> PlanRoute(const WalkGraph& graph, int start_node, double length_m,
                           std::mt19937_64& rng, const std::function<bool(int)>& allowed = {});

struct EncoderReading {
  double t = 0;
  int64_t left = 0, right = 0;  // cumulative ticks
};

// Samples the encoders at WheelOptions::rate_hz: true wheel travel distorted by
// radius errors and slip, quantised to whole pulses.
std::vector<EncoderReading> SimulateEncoders(const Trajectory& trajectory, const WheelOptions& wheels,
                                             uint64_t seed);

// Dead reckoning from encoder readings with the nominal wheel geometry.
std::vector<PlanarState> IntegrateEncoders(const std::vector<EncoderReading>& readings,
                                           const WheelOptions& wheels, const PlanarState& start);

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_PLATFORM_H_

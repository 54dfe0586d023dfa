#include "platform.h"

#include <algorithm>
#include <cmath>

#include "locforge/error.h"

namespace locforge::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

double WrapAngle(double a) { return std::remainder(a, 2 * kPi); }

double Approach(double current, double target, double max_step) {
  return current + std::clamp(target - current, -max_step, max_step);
}

}  // namespace

bool WheelOptions::Check(std::string* why) const {
  if (radius <= 0 || axle <= 0) return *why = "wheel radius and axle must be positive", false;
  if (pulses_per_rev < 1) return *why = "pulses_per_rev must be >= 1", false;
  if (rate_hz <= 0) return *why = "encoder rate must be positive", false;
  if (scale_error < 0 || differential_error < 0 || slip_sigma < 0)
    return *why = "encoder noise must be >= 0", false;
  return true;
}

PlanarState Advance(const PlanarState& s, double tau) {
  PlanarState out = s;
  out.t = s.t + tau;
  if (std::abs(s.w) > 1e-9) {
    const double yaw1 = s.yaw + s.w * tau;
    out.x += s.v / s.w * (std::sin(yaw1) - std::sin(s.yaw));
    out.y -= s.v / s.w * (std::cos(yaw1) - std::cos(s.yaw));
    out.yaw = yaw1;
  } else {
    out.x += s.v * tau * std::cos(s.yaw);
    out.y += s.v * tau * std::sin(s.yaw);
  }
  return out;
}

double Trajectory::Distance() const {
  double d = 0;
  for (size_t i = 1; i < states.size(); ++i) d += std::abs(states[i - 1].v) * (states[i].t - states[i - 1].t);
  return d;
}

PlanarState Trajectory::StateAt(double t) const {
  if (states.empty()) return {};
  if (t <= states.front().t) return states.front();
  if (t >= states.back().t) return states.back();
  const size_t i = std::min(states.size() - 2, static_cast<size_t>((t - states.front().t) / dt));
  return Advance(states[i], t - states[i].t);
}

Pose Trajectory::PoseAt(double t) const {
  const PlanarState s = StateAt(t);
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(s.yaw, Eigen::Vector3d::UnitZ())),
              Eigen::Vector3d(s.x, s.y, height));
}

Trajectory Drive(const std::vector<Eigen::Vector2d>& waypoints, const std::vector<bool>& spins,
                 double start_yaw, const MotionLimits& lim, double max_duration, double height,
                 double dt) {
  Trajectory traj;
  traj.dt = dt;
  traj.height = height;
  if (waypoints.empty()) throw Error("Drive: no waypoints");
  PlanarState s;
  s.x = waypoints[0].x();
  s.y = waypoints[0].y();
  s.yaw = start_yaw;
  const auto spin_at = [&](size_t i) { return i < spins.size() && spins[i]; };
  size_t target = 1;
  double spin_left = 0;  // radians still to spin in place
  while (s.t < max_duration && target < waypoints.size()) {
    double v_goal = 0, w_goal = 0;
    if (spin_left > 0) {
      // Brake to a stop, then spin; slow the rotation down for the last bit.
      w_goal = std::min(lim.max_turn_rate, std::sqrt(2 * lim.max_turn_accel * spin_left));
      if (std::abs(s.v) > 1e-6) w_goal = 0;
      spin_left -= std::abs(s.w) * dt;
    } else {
      const Eigen::Vector2d to = waypoints[target] - Eigen::Vector2d(s.x, s.y);
      const double err = WrapAngle(std::atan2(to.y(), to.x()) - s.yaw);
      const bool last = target + 1 == waypoints.size();
      w_goal = std::clamp(3.0 * err, -lim.max_turn_rate, lim.max_turn_rate);
      const double align = std::pow(std::max(0.0, std::cos(err)), 6);
      v_goal = lim.max_speed * align;
      if (last || spin_at(target)) v_goal = std::min(v_goal, std::sqrt(2 * lim.max_accel * to.norm()));
      if (to.norm() < (last || spin_at(target) ? 0.05 : 0.5)) {
        if (spin_at(target)) spin_left = 2 * kPi;
        ++target;
        continue;
      }
    }
    s.v = Approach(s.v, v_goal, lim.max_accel * dt);
    s.w = Approach(s.w, w_goal, lim.max_turn_accel * dt);
    traj.states.push_back(s);
    s = Advance(s, dt);
  }
  s.v = s.w = 0;
  traj.states.push_back(s);
  return traj;
}

std::vector<int> PlanRoute(const WalkGraph& graph, int start_node, double length_m,
                           std::mt19937_64& rng, const std::function<bool(int)>& allowed) {
  const auto neighbours = graph.Neighbours();
  std::vector<int> route{start_node};
  double length = 0;
  int prev = -1;
  while (length < length_m) {
    const int node = route.back();
    std::vector<int> options;
    for (int n : neighbours[node])
      if (n != prev && (!allowed || allowed(n))) options.push_back(n);
    if (options.empty() && prev >= 0) options.push_back(prev);  // dead end: go back
    if (options.empty()) break;
    const int next = options[rng() % options.size()];
    length += (graph.nodes[next] - graph.nodes[node]).norm();
    prev = node;
    route.push_back(next);
  }
  return route;
}

std::vector<EncoderReading> SimulateEncoders(const Trajectory& traj, const WheelOptions& wheels,
                                             uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0, 1);
  // Per-sequence effective radius errors: the wheels turn 1/(1+e) per metre.
  const double common = wheels.scale_error * gauss(rng);
  const double diff = wheels.differential_error * gauss(rng);
  const double e_left = common - diff / 2, e_right = common + diff / 2;
  const double metres_per_tick = 2 * kPi * wheels.radius / wheels.pulses_per_rev;
  const double period = 1.0 / wheels.rate_hz;

  std::vector<EncoderReading> out;
  double left = 0, right = 0;  // measured wheel travel (m)
  double next_sample = 0;
  for (size_t i = 0; i < traj.states.size(); ++i) {
    const PlanarState& s = traj.states[i];
    while (next_sample <= s.t + 1e-12) {
      // Interpolate inside the step so sampling does not depend on dt.
      const double tau = next_sample - s.t;
      const double l = left + (s.v - s.w * wheels.axle / 2) * tau / (1 + e_left);
      const double r = right + (s.v + s.w * wheels.axle / 2) * tau / (1 + e_right);
      out.push_back({next_sample, static_cast<int64_t>(std::floor(l / metres_per_tick)),
                     static_cast<int64_t>(std::floor(r / metres_per_tick))});
      next_sample += period;
    }
    if (i + 1 == traj.states.size()) break;
    const double h = traj.states[i + 1].t - s.t;
    const double dl = (s.v - s.w * wheels.axle / 2) * h, dr = (s.v + s.w * wheels.axle / 2) * h;
    left += dl / (1 + e_left) + wheels.slip_sigma * std::sqrt(std::abs(dl)) * gauss(rng);
    right += dr / (1 + e_right) + wheels.slip_sigma * std::sqrt(std::abs(dr)) * gauss(rng);
  }
  return out;
}

std::vector<PlanarState> IntegrateEncoders(const std::vector<EncoderReading>& readings,
                                           const WheelOptions& wheels, const PlanarState& start) {
  const double metres_per_tick = 2 * kPi * wheels.radius / wheels.pulses_per_rev;
  std::vector<PlanarState> out;
  PlanarState s = start;
  for (size_t i = 0; i < readings.size(); ++i) {
    if (i > 0) {
      const double dl = (readings[i].left - readings[i - 1].left) * metres_per_tick;
      const double dr = (readings[i].right - readings[i - 1].right) * metres_per_tick;
      const double ds = 0.5 * (dl + dr), dyaw = (dr - dl) / wheels.axle;
      s.x += ds * std::cos(s.yaw + dyaw / 2);
      s.y += ds * std::sin(s.yaw + dyaw / 2);
      s.yaw += dyaw;
    }
    s.t = readings[i].t;
    out.push_back(s);
  }
  return out;
}

}  // namespace locforge::sim

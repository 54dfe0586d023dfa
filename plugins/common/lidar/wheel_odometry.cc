#include "wheel_odometry.h"

#include <algorithm>
#include <cmath>

#include "locforge/error.h"
#include "locforge/params.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"

namespace locforge::lidar {

bool WheelParams::Check(std::string* why) const {
  if (radius > 0 && axle > 0 && pulses_per_rev > 0) return true;
  if (why) *why = "wheel radius, axle and pulses_per_rev must all be > 0";
  return false;
}

namespace {
// One unicycle step with the midpoint rule (see the header).
Pose IntegrateStep(const Pose& pose, double d_left, double d_right, double axle) {
  const double ds = 0.5 * (d_left + d_right);
  const double dtheta = (d_right - d_left) / axle;
  const Eigen::Vector3d step(ds * std::cos(0.5 * dtheta), ds * std::sin(0.5 * dtheta), 0);
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(dtheta, Eigen::Vector3d::UnitZ()));
  return pose * Pose(turn, step);
}
}  // namespace

WheelOdometry::WheelOdometry(const WheelParams& params, std::vector<WheelTicks> ticks,
                             double seconds_per_unit, double max_gap_s)
    : params_(params), margin_units_(0.2 / seconds_per_unit) {
  std::string why;
  if (!params.Check(&why)) throw ParamError(why);
  std::stable_sort(ticks.begin(), ticks.end(),
                   [](const WheelTicks& a, const WheelTicks& b) { return a.timestamp < b.timestamp; });
  const double metres_per_pulse = 2 * M_PI * params.radius / params.pulses_per_rev;
  const double max_gap_units = max_gap_s / seconds_per_unit;
  for (size_t i = 0; i < ticks.size(); ++i) {
    const bool new_segment = i == 0 || ticks[i].timestamp - ticks[i - 1].timestamp > max_gap_units ||
                             ticks[i].left < ticks[i - 1].left - 1000000 ||
                             ticks[i].right < ticks[i - 1].right - 1000000;
    if (new_segment) {
      segments_.push_back({{static_cast<double>(ticks[i].timestamp), Pose(), 0.0}});
      continue;
    }
    const Sample& last = segments_.back().back();
    const double d_left = (ticks[i].left - ticks[i - 1].left) * metres_per_pulse;
    const double d_right = (ticks[i].right - ticks[i - 1].right) * metres_per_pulse;
    segments_.back().push_back({static_cast<double>(ticks[i].timestamp),
                                IntegrateStep(last.pose, d_left, d_right, params.axle),
                                last.distance + 0.5 * (std::abs(d_left) + std::abs(d_right))});
  }
}

WheelOdometry WheelOdometry::FromKapture(const fs::path& root, const WheelParams& override_params,
                                         const std::string& sensor_id) {
  kapture::Kapture k(root);
  const kapture::Sensor* sensor = nullptr;
  for (const auto* s : k.sensors().OfType("wheel_encoder"))
    if (sensor_id.empty() || s->id == sensor_id) sensor = s;
  WheelParams p;
  if (sensor) {
    const std::string file = (root / kapture::layout::kSensors).string();
    const char* names[3] = {"radius", "axle", "pulses_per_rev"};
    double* fields[3] = {&p.radius, &p.axle, &p.pulses_per_rev};
    for (int i = 0; i < 3 && i < static_cast<int>(sensor->params.size()); ++i)
      if (!ParseDouble(sensor->params[i], fields[i]) || *fields[i] <= 0)
        throw InputError(file, 0, names[i],
                         "wheel_encoder sensor '" + sensor->id + "': expected a positive number, got '" +
                             sensor->params[i] + "'");
  }
  if (override_params.radius > 0) p.radius = override_params.radius;
  if (override_params.axle > 0) p.axle = override_params.axle;
  if (override_params.pulses_per_rev > 0) p.pulses_per_rev = override_params.pulses_per_rev;
  if (!sensor && !(override_params.radius > 0 && override_params.axle > 0))
    throw InputError((root / kapture::layout::kSensors).string(), 0, "wheel_encoder",
                     "no wheel_encoder sensor and no radius/axle given as parameters");
  const fs::path records = root / kapture::layout::RecordsFile("wheel_encoder");
  if (!fs::exists(records))
    throw InputError(records.string(), 0, "", "missing: wheel odometry needs encoder records");
  kapture::RecordsReader<kapture::GenericRecord> reader(records);
  std::vector<WheelTicks> ticks;
  kapture::GenericRecord r;
  int64_t line = 0;
  while (reader.Next(&r)) {
    ++line;
    if (sensor && r.device_id != sensor->id) continue;
    WheelTicks t;
    t.timestamp = r.timestamp;
    if (r.values.size() < 2 || !ParseInt(r.values[0], &t.left) || !ParseInt(r.values[1], &t.right))
      throw InputError(records.string(), line, "left_ticks, right_ticks",
                       "expected two integer tick counts");
    ticks.push_back(t);
  }
  if (ticks.size() < 2) throw InputError(records.string(), 0, "", "fewer than 2 encoder records");
  return WheelOdometry(p, std::move(ticks));
}

const WheelOdometry::Segment& WheelOdometry::SegmentOf(double t) const {
  for (const auto& s : segments_)
    if (t >= s.front().t - margin_units_ && t <= s.back().t + margin_units_) return s;
  throw Error("wheel odometry: no encoder data at time " + FormatDouble(t));
}

bool WheelOdometry::Covers(double t) const {
  for (const auto& s : segments_)
    if (t >= s.front().t - margin_units_ && t <= s.back().t + margin_units_) return true;
  return false;
}

bool WheelOdometry::SameSegment(double t_a, double t_b) const {
  return Covers(t_a) && Covers(t_b) && &SegmentOf(t_a) == &SegmentOf(t_b);
}

WheelOdometry::Sample WheelOdometry::At(const Segment& s, double t) {
  if (t <= s.front().t) return s.front();
  if (t >= s.back().t) return s.back();
  const auto it = std::upper_bound(s.begin(), s.end(), t,
                                   [](double v, const Sample& x) { return v < x.t; });
  const Sample& b = *it;
  const Sample& a = *(it - 1);
  const double alpha = (t - a.t) / (b.t - a.t);
  return {t, Interpolate(a.pose, b.pose, alpha), a.distance + alpha * (b.distance - a.distance)};
}

Pose WheelOdometry::PlatformPose(double t) const { return At(SegmentOf(t), t).pose; }

Pose WheelOdometry::Relative(double t_a, double t_b) const {
  const Segment& s = SegmentOf(t_a);
  if (&s != &SegmentOf(t_b))
    throw Error("wheel odometry: times " + FormatDouble(t_a) + " and " + FormatDouble(t_b) +
                " are in different segments");
  return At(s, t_a).pose.Inverse() * At(s, t_b).pose;
}

double WheelOdometry::Distance(double t_a, double t_b) const {
  const Segment& s = SegmentOf(t_a);
  return std::abs(At(s, t_b).distance - At(s, t_a).distance);
}

}  // namespace locforge::lidar

#include "keyframes.h"

#include <cmath>

namespace locforge::lidar {

std::string SequenceOfScan(const std::string& path) {
  std::vector<std::string> parts;
  for (const auto& c : fs::path(path)) parts.push_back(c.generic_string());
  const size_t i = (!parts.empty() && parts[0] == "undistorted") ? 1 : 0;
  return parts.size() >= i + 2 ? parts[i] : std::string();
}

bool MotionModel::Covers(Timestamp t) const { return !odometry_ || odometry_->Covers(static_cast<double>(t)); }

bool MotionModel::SameSegment(const std::string& seq_a, Timestamp a, const std::string& seq_b, Timestamp b) const {
  if (seq_a != seq_b) return false;
  if (odometry_) return odometry_->SameSegment(static_cast<double>(a), static_cast<double>(b));
  return std::abs(static_cast<double>(b - a)) * seconds_per_unit_ <= max_gap_;
}

Pose MotionModel::Relative(Timestamp a, Timestamp b) const {
  return odometry_ ? odometry_->Relative(static_cast<double>(a), static_cast<double>(b)) : Pose();
}

double MotionModel::Distance(Timestamp a, Timestamp b) const {
  return odometry_ ? odometry_->Distance(static_cast<double>(a), static_cast<double>(b)) : 0.0;
}

std::vector<KeyframeChoice> ChooseKeyframes(const std::vector<ScanStamp>& scans, const MotionModel& motion,
                                            double keyframe_distance_m, double keyframe_angle_rad) {
  std::vector<KeyframeChoice> out;
  for (size_t i = 0; i < scans.size(); ++i) {
    const ScanStamp& s = scans[i];
    if (!motion.Covers(s.timestamp)) continue;
    const ScanStamp* last = out.empty() ? nullptr : &scans[out.back().scan];
    const bool start = !last || !motion.SameSegment(last->sequence, last->timestamp, s.sequence, s.timestamp);
    double travelled = 0;
    if (!start && motion.has_odometry()) {
      const Pose rel = motion.Relative(last->timestamp, s.timestamp);
      if (rel.t.norm() < keyframe_distance_m && Eigen::AngleAxisd(rel.q).angle() < keyframe_angle_rad) continue;
      travelled = out.back().travelled + motion.Distance(last->timestamp, s.timestamp);
    }
    out.push_back({i, start, travelled});
  }
  return out;
}

YawScaleFit FitYawScale(const std::vector<std::pair<double, double>>& pairs, const YawScaleOptions& options) {
  double oo = 0, or_ = 0;
  YawScaleFit fit;
  for (const auto& [odometry, registered] : pairs) {
    oo += odometry * odometry;
    or_ += odometry * registered;
    fit.turned_rad += std::abs(odometry);
  }
  if (oo > 0) fit.k = or_ / oo;
  fit.applied = fit.turned_rad >= options.min_turned_rad && std::abs(fit.k - 1) <= options.max_deviation;
  return fit;
}

}  // namespace locforge::lidar

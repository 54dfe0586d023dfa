#include "camera_rig.h"

#include <algorithm>
#include <cmath>

#include "locforge/units.h"

namespace locforge::sim {
PinholeCamera PinholeCamera::FromFov(int width, int height, double hfov_deg, double vfov_deg) {
  PinholeCamera c;
  c.width = width;
  c.height = height;
  c.fx = 0.5 * width / std::tan(0.5 * hfov_deg * kDeg);
  c.fy = 0.5 * height / std::tan(0.5 * vfov_deg * kDeg);
  c.cx = 0.5 * width;
  c.cy = 0.5 * height;
  return c;
}

PinholeCamera PinholeCamera::FromDiagonalFov(int width, int height, double dfov_deg) {
  PinholeCamera c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = 0.5 * std::hypot(width, height) / std::tan(0.5 * dfov_deg * kDeg);
  c.cx = 0.5 * width;
  c.cy = 0.5 * height;
  return c;
}

bool RigOptions::Check(std::string* why) const {
  if (!(image_scale > 0 && image_scale <= 1)) return *why = "image_scale must be in (0, 1]", false;
  if (!industrial && !phones) return *why = "the rig needs at least one camera group", false;
  if (clock_offset_sigma_s < 0 || jitter_sigma_s < 0) return *why = "clock noise must be >= 0", false;
  if (lidar_azimuth_resolution_deg <= 0 || lidar_range_sigma < 0)
    return *why = "lidar resolution must be > 0 and noise >= 0", false;
  return true;
}

Pose CameraMount(double azimuth_deg, double tilt_deg, const Eigen::Vector3d& position) {
  const double az = azimuth_deg * kDeg, tilt = tilt_deg * kDeg;
  const Eigen::Vector3d forward(std::cos(az) * std::cos(tilt), std::sin(az) * std::cos(tilt), std::sin(tilt));
  const Eigen::Vector3d right(std::sin(az), -std::cos(az), 0);
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Matrix3d R;  // columns: camera axes in the platform frame
  R.col(0) = right;
  R.col(1) = down;
  R.col(2) = forward;
  return Pose(Eigen::Quaterniond(R), position);
}

Rig MakeRig(const RigOptions& o, uint64_t seed) {
  std::mt19937_64 rng(seed * 0x2545F4914F6CDD1Dull + 5);
  std::normal_distribution<double> gauss(0, 1);
  std::uniform_real_distribution<double> u01(0, 1);
  const auto scaled = [&](int n) { return std::max(8, static_cast<int>(std::lround(n * o.image_scale))); };
  Rig rig;
  if (o.industrial)
    for (int i = 0; i < 6; ++i) {
      CameraOptions c;
      c.id = "ind_" + std::to_string(i);
      c.model = "industrial 2592x2048 global shutter";
      c.intrinsics = PinholeCamera::FromFov(scaled(2592), scaled(2048), 79.4, 63.0);
      const double az = 60.0 * i;
      c.T_platform_camera = CameraMount(az, 10, Eigen::Vector3d(0.12 * std::cos(az * kDeg), 0.12 * std::sin(az * kDeg), 1.55));
      c.rate_hz = 2.5;
      c.phase_s = 0.4 * u01(rng);
      c.clock_offset_s = o.clock_offset_sigma_s * gauss(rng);
      c.jitter_s = o.jitter_sigma_s;
      rig.cameras.push_back(c);
    }
  if (o.phones)
    for (int i = 0; i < 4; ++i) {
      CameraOptions c;
      c.id = "phone_" + std::to_string(i);
      c.model = "smartphone 2160x2880 portrait";
      c.intrinsics = PinholeCamera::FromDiagonalFov(scaled(2160), scaled(2880), 77.0);
      const double az = 45.0 + 90.0 * i;
      c.T_platform_camera = CameraMount(az, 0, Eigen::Vector3d(0.1 * std::cos(az * kDeg), 0.1 * std::sin(az * kDeg), 1.70));
      c.rate_hz = 1.0;
      c.phase_s = u01(rng);
      c.clock_offset_s = o.clock_offset_sigma_s * gauss(rng);
      c.jitter_s = o.jitter_sigma_s;
      rig.cameras.push_back(c);
    }
  LidarOptions h;
  h.id = "lidar_h";
  h.T_platform_lidar = Pose(Eigen::Quaterniond::Identity(), {0, 0, 0.9});
  h.azimuth_resolution_deg = o.lidar_azimuth_resolution_deg;
  h.range_sigma = o.lidar_range_sigma;
  LidarOptions v = h;
  v.id = "lidar_v";
  // Spin axis along the platform's x axis: sweeps vertical planes (push-broom).
  v.T_platform_lidar = Pose(Eigen::Quaterniond(Eigen::AngleAxisd(90 * kDeg, Eigen::Vector3d::UnitY())), {0, 0, 1.95});
  rig.lidars = {h, v};
  return rig;
}

std::vector<Capture> CaptureTimes(const CameraOptions& camera, double duration, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> jitter(0, camera.jitter_s);
  std::vector<Capture> out;
  for (int k = 0;; ++k) {
    const double nominal = camera.phase_s + k / camera.rate_hz;
    if (nominal >= duration) break;
    Capture c;
    c.index = k;
    c.true_time = std::clamp(nominal + jitter(rng), 0.0, duration);
    c.stamp = nominal + camera.clock_offset_s;  // the scheduled time on the camera's clock
    out.push_back(c);
  }
  return out;
}

}  // namespace locforge::sim

#include "metrics.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "locforge/error.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"

namespace locforge::eval {

namespace {
std::vector<std::vector<double>> ReadNumberRows(const fs::path& path, size_t columns, const char* what) {
  std::istringstream in(ReadFile(path));
  std::vector<std::vector<double>> rows;
  std::string line;
  int64_t number = 0;
  while (std::getline(in, line)) {
    ++number;
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream s(line);
    std::vector<double> v;
    double x;
    while (s >> x) v.push_back(x);
    if (v.size() != columns || !s.eof())
      throw InputError(path.string(), number, what,
                       "expected " + std::to_string(columns) + " numbers, got " + std::to_string(v.size()));
    rows.push_back(std::move(v));
  }
  return rows;
}

double AngleDeg(const Eigen::Quaterniond& q) {
  return std::abs(Eigen::AngleAxisd(q.normalized()).angle()) * 180.0 / M_PI;
}
}  // namespace

Trajectory ReadTum(const fs::path& path) {
  Trajectory t;
  for (const auto& v : ReadNumberRows(path, 8, "timestamp tx ty tz qx qy qz qw"))
    t.push_back({v[0], Pose(Eigen::Quaterniond(v[7], v[4], v[5], v[6]), {v[1], v[2], v[3]})});
  return t;
}

Trajectory ReadKitti(const fs::path& path) {
  Trajectory t;
  for (const auto& v : ReadNumberRows(path, 12, "r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz")) {
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = v[4 * r + c];
    // Like evo, keep the matrix's own rotation (orthonormalised through the quaternion).
    t.push_back({static_cast<double>(t.size()), Pose::FromMatrix(m), m});
  }
  return t;
}

Trajectory ReadKaptureTrajectory(const fs::path& root, const std::string& device, double seconds_per_unit) {
  const fs::path file = root / kapture::layout::kTrajectories;
  const kapture::Trajectories all = kapture::ReadTrajectories(file);
  Trajectory t;
  for (const auto& [key, pose] : all.poses)
    if (key.second == device) t.push_back({key.first * seconds_per_unit, pose.Inverse()});
  if (t.empty()) throw InputError(file.string(), 0, "device_id", "no pose of device '" + device + "'");
  return t;
}

std::string FormatTum(const Trajectory& t) {
  std::ostringstream o;
  o << std::setprecision(17);
  for (const auto& p : t) {
    const auto& q = p.T_world_device.q;
    const auto& x = p.T_world_device.t;
    o << p.time << ' ' << x.x() << ' ' << x.y() << ' ' << x.z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z()
      << ' ' << q.w() << '\n';
  }
  return o.str();
}

std::string FormatKitti(const Trajectory& t) {
  std::ostringstream o;
  o << std::setprecision(17);
  for (const auto& p : t) {
    const Eigen::Matrix4d m = p.T_world_device.Matrix();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) o << m(r, c) << (r == 2 && c == 3 ? '\n' : ' ');
  }
  return o.str();
}

void Associate(double max_diff, Trajectory* reference, Trajectory* estimate) {
  const bool estimate_longer = estimate->size() > reference->size();
  Trajectory& shorter = estimate_longer ? *reference : *estimate;
  Trajectory& longer = estimate_longer ? *estimate : *reference;
  Trajectory a, b;
  for (const auto& p : shorter) {
    // Nearest stamp of the (sorted) longer trajectory; first one on ties, like argmin.
    auto it = std::lower_bound(longer.begin(), longer.end(), p.time,
                               [](const StampedPose& s, double t) { return s.time < t; });
    const StampedPose* best = nullptr;
    if (it != longer.begin()) best = &*(it - 1);
    if (it != longer.end() && (!best || std::abs(it->time - p.time) < std::abs(best->time - p.time))) best = &*it;
    if (best && std::abs(best->time - p.time) <= max_diff) {
      a.push_back(p);
      b.push_back(*best);
    }
  }
  shorter = std::move(a);
  longer = std::move(b);
}

Similarity Umeyama(const std::vector<Eigen::Vector3d>& x, const std::vector<Eigen::Vector3d>& y, bool with_scale) {
  if (x.size() != y.size() || x.size() < 3) throw Error("Umeyama alignment needs >= 3 associated positions");
  const double n = static_cast<double>(x.size());
  Eigen::Vector3d mx = Eigen::Vector3d::Zero(), my = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < x.size(); ++i) {
    mx += x[i];
    my += y[i];
  }
  mx /= n;
  my /= n;
  double sigma_x = 0;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < x.size(); ++i) {
    sigma_x += (x[i] - mx).squaredNorm();
    cov += (y[i] - my) * (x[i] - mx).transpose();
  }
  sigma_x /= n;
  cov /= n;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) S(2, 2) = -1;
  Similarity out;
  out.R = svd.matrixU() * S * svd.matrixV().transpose();
  out.scale = with_scale ? (svd.singularValues().asDiagonal() * S).trace() / sigma_x : 1.0;
  out.t = my - out.scale * out.R * mx;
  return out;
}

Similarity Align(Alignment alignment, const Trajectory& reference, Trajectory* estimate) {
  Similarity s;
  if (alignment == Alignment::kNone || estimate->empty()) return s;
  if (alignment == Alignment::kFirst) {
    const Pose T = reference.front().T_world_device * estimate->front().T_world_device.Inverse();
    s.R = T.R();
    s.t = T.t;
  } else {
    std::vector<Eigen::Vector3d> x, y;
    for (size_t i = 0; i < estimate->size(); ++i) {
      x.push_back((*estimate)[i].T_world_device.t);
      y.push_back(reference[i].T_world_device.t);
    }
    s = Umeyama(x, y, alignment == Alignment::kSim3);
  }
  const Eigen::Quaterniond q(s.R);
  for (auto& p : *estimate) {
    p.T_world_device = Pose(q * p.T_world_device.q, s.scale * (s.R * p.T_world_device.t) + s.t);
    if (p.raw) {
      p.raw->topLeftCorner<3, 3>() = s.R * p.raw->topLeftCorner<3, 3>();
      p.raw->topRightCorner<3, 1>() = p.T_world_device.t;
    }
  }
  return s;
}

Statistics ComputeStatistics(std::vector<double> e) {
  Statistics s;
  s.count = e.size();
  if (e.empty()) return s;
  const double n = static_cast<double>(e.size());
  for (double v : e) {
    s.sse += v * v;
    s.mean += v;
  }
  s.mean /= n;
  s.rmse = std::sqrt(s.sse / n);
  for (double v : e) s.std += (v - s.mean) * (v - s.mean);
  s.std = std::sqrt(s.std / n);
  std::sort(e.begin(), e.end());
  s.min = e.front();
  s.max = e.back();
  s.median = e.size() % 2 ? e[e.size() / 2] : 0.5 * (e[e.size() / 2 - 1] + e[e.size() / 2]);
  return s;
}

Errors AbsolutePoseErrors(const Trajectory& reference, const Trajectory& estimate) {
  if (reference.size() != estimate.size()) throw Error("APE needs associated trajectories of equal length");
  Errors e;
  for (size_t i = 0; i < reference.size(); ++i) {
    const Pose E = reference[i].T_world_device.Inverse() * estimate[i].T_world_device;
    e.translation.push_back((reference[i].T_world_device.t - estimate[i].T_world_device.t).norm());
    e.rotation.push_back(AngleDeg(E.q));
  }
  return e;
}

std::vector<std::pair<size_t, size_t>> RelativePairs(const Trajectory& estimate, double delta, DeltaUnit unit,
                                                     bool all_pairs) {
  std::vector<std::pair<size_t, size_t>> pairs;
  const size_t n = estimate.size();
  if (unit == DeltaUnit::kFrames) {
    const size_t d = static_cast<size_t>(std::max(1.0, std::round(delta)));
    if (all_pairs) {
      for (size_t i = 0; i + d < n; ++i) pairs.emplace_back(i, i + d);
    } else {
      for (size_t i = 0; i + d < n; i += d) pairs.emplace_back(i, i + d);
    }
    return pairs;
  }
  if (all_pairs) {
    std::vector<double> path(n, 0.0);
    for (size_t i = 1; i < n; ++i)
      path[i] = path[i - 1] + (estimate[i].T_world_device.t - estimate[i - 1].T_world_device.t).norm();
    for (size_t i = 0; i < n; ++i) {
      const auto it = std::lower_bound(path.begin() + i, path.end(), path[i] + delta);
      if (it != path.end()) pairs.emplace_back(i, static_cast<size_t>(it - path.begin()));
    }
    return pairs;
  }
  // evo's filter_pairs_by_path: an id each time `delta` metres have been travelled.
  std::vector<size_t> ids;
  double travelled = 0;
  for (size_t i = 1; i < n; ++i) {
    travelled += (estimate[i].T_world_device.t - estimate[i - 1].T_world_device.t).norm();
    if (travelled >= delta) {
      ids.push_back(i);
      travelled = 0;
    }
  }
  for (size_t k = 1; k < ids.size(); ++k) pairs.emplace_back(ids[k - 1], ids[k]);
  return pairs;
}

Errors RelativePoseErrors(const Trajectory& reference, const Trajectory& estimate, double delta, DeltaUnit unit,
                          bool all_pairs) {
  if (reference.size() != estimate.size()) throw Error("RPE needs associated trajectories of equal length");
  Errors e;
  // evo's se3_inverse: (R^T, -R^T t), applied to the matrices as read.
  auto inverse = [](const Eigen::Matrix4d& m) {
    Eigen::Matrix4d i = Eigen::Matrix4d::Identity();
    i.topLeftCorner<3, 3>() = m.topLeftCorner<3, 3>().transpose();
    i.topRightCorner<3, 1>() = -m.topLeftCorner<3, 3>().transpose() * m.topRightCorner<3, 1>();
    return i;
  };
  for (const auto& [i, j] : RelativePairs(estimate, delta, unit, all_pairs)) {
    const Eigen::Matrix4d Q = inverse(reference[i].Matrix()) * reference[j].Matrix();
    const Eigen::Matrix4d P = inverse(estimate[i].Matrix()) * estimate[j].Matrix();
    const Eigen::Matrix4d E = inverse(Q) * P;
    e.translation.push_back(E.topRightCorner<3, 1>().norm());
    // evo's so3_log angle: arccos((trace - 1) / 2), clipped.
    const double c = std::clamp((E.topLeftCorner<3, 3>().trace() - 1) / 2, -1.0, 1.0);
    e.rotation.push_back(std::acos(c) * 180.0 / M_PI);
  }
  return e;
}

}  // namespace locforge::eval

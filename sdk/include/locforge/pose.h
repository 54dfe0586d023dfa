// Rigid transforms and time.
//
// Convention, stated once: a Pose T_a_b maps points from frame b into frame a
// (x_a = T_a_b * x_b). kapture's trajectories.txt stores world-to-device poses,
// i.e. T_device_world, as (qw, qx, qy, qz, tx, ty, tz); COLMAP's images.txt
// stores the same world-to-camera transform. So a trajectory entry is read
// straight into a Pose and the device centre in the world is
// T_device_world.Inverse().t = -R^T t (Pose::Center()).
#ifndef LOCFORGE_POSE_H_
#define LOCFORGE_POSE_H_

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>

namespace locforge {

// kapture timestamps are integers in a unit chosen by the dataset (commonly
// microseconds or nanoseconds); the SDK never assumes one.
using Timestamp = int64_t;

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

struct Pose {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();  // rotation R
  Eigen::Vector3d t = Eigen::Vector3d::Zero();            // translation

  Pose() = default;
  Pose(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation)
      : q(rotation.normalized()), t(translation) {}

  static Pose Identity() { return Pose(); }
  static Pose FromMatrix(const Eigen::Matrix4d& m);
  Eigen::Matrix4d Matrix() const;
  Eigen::Matrix3d R() const { return q.toRotationMatrix(); }

  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return q * p + t; }
  Pose operator*(const Pose& o) const { return Pose(q * o.q, q * o.t + t); }
  Pose Inverse() const {
    const Eigen::Quaterniond qi = q.conjugate();
    return Pose(qi, -(qi * t));
  }
  // For a world-to-device pose: the device centre in world coordinates.
  Eigen::Vector3d Center() const { return -(q.conjugate() * t); }
};

// SE(3) exponential and logarithm; tangent order (rx, ry, rz, tx, ty, tz),
// rotation first, as in the registration information matrices of abi.h.
Pose ExpSE3(const Vector6d& xi);
Vector6d LogSE3(const Pose& T);
// SO(3) helpers.
Eigen::Quaterniond ExpSO3(const Eigen::Vector3d& w);
Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q);

// Interpolates on SE(3) by slerp of the rotation and linear translation,
// alpha in [0, 1] (0 -> a, 1 -> b).
Pose Interpolate(const Pose& a, const Pose& b, double alpha);

// Geodesic angle between two rotations, in degrees.
double RotationAngleDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b);

}  // namespace locforge

#endif  // LOCFORGE_POSE_H_

#include "point_uncertainty.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>

namespace locforge::localization {

namespace {
// Eigenvalues of the information below this share of the largest are raised
// to it: the covariance stays finite along an unconstrained direction.
constexpr double kMinInformationShare = 1e-8;
}  // namespace

Eigen::Matrix3d TriangulationCovariance(const Eigen::Vector3d& point, const std::vector<MapView>& views) {
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  for (const MapView& v : views) {
    const Eigen::Vector3d ray = point - v.centre;
    const double d = ray.norm();
    if (d <= 0) continue;
    const Eigen::Vector3d u = ray / d;
    information += (v.focal * v.focal / (d * d)) * (Eigen::Matrix3d::Identity() - u * u.transpose());
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(information);
  const double largest = eigen.eigenvalues().maxCoeff();
  if (!(largest > 0)) return Eigen::Matrix3d::Zero();
  const Eigen::Vector3d inverse =
      eigen.eigenvalues().cwiseMax(kMinInformationShare * largest).cwiseInverse();
  return eigen.eigenvectors() * inverse.asDiagonal() * eigen.eigenvectors().transpose();
}

Eigen::Matrix2d ReprojectionWhitening(const Pose& camera_from_world, double focal,
                                      const Eigen::Vector3d& point, const Eigen::Matrix3d& covariance) {
  const Eigen::Vector3d p = camera_from_world * point;
  if (p.z() <= 1e-12) return Eigen::Matrix2d::Identity();
  Eigen::Matrix<double, 2, 3> projection;
  projection << 1 / p.z(), 0, -p.x() / (p.z() * p.z()), 0, 1 / p.z(), -p.y() / (p.z() * p.z());
  const Eigen::Matrix<double, 2, 3> jacobian = focal * projection * camera_from_world.R();
  const Eigen::Matrix2d total =
      Eigen::Matrix2d::Identity() + jacobian * covariance * jacobian.transpose();
  // total = L L^T, so |L^-1 r|^2 = r^T total^-1 r.
  const Eigen::Matrix2d l = total.llt().matrixL();
  return l.inverse();
}

}  // namespace locforge::localization

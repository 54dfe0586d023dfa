#include "scan_context.h"

#include <algorithm>
#include <cmath>

#include "locforge/error.h"

namespace locforge::lidar {

bool ScanContextOptions::Check(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (rings < 1 || sectors < 4) return fail("scan context: rings must be >= 1 and sectors >= 4");
  if (!(max_radius_m > 0)) return fail("scan context: max_radius_m must be > 0");
  if (!(max_height_m > min_height_m)) return fail("scan context: max_height_m must exceed min_height_m");
  return true;
}

ScanContext MakeScanContext(const Cloud& scan, const ScanContextOptions& o) {
  std::string why;
  if (!o.Check(&why)) throw ParamError(why);
  ScanContext sc;
  sc.grid = Eigen::MatrixXf::Zero(o.rings, o.sectors);
  for (const Eigen::Vector3f& p : scan.points) {
    if (p.z() < o.min_height_m || p.z() > o.max_height_m) continue;
    const double r = std::hypot(p.x(), p.y());
    if (r >= o.max_radius_m || r <= 0) continue;
    const double azimuth = std::atan2(p.y(), p.x()) + M_PI;  // [0, 2 pi]
    const int ring = std::min(o.rings - 1, static_cast<int>(r / o.max_radius_m * o.rings));
    const int sector = std::min(o.sectors - 1, static_cast<int>(azimuth / (2 * M_PI) * o.sectors));
    // Heights above the band's floor, so an occupied bin is never 0.
    const float value = static_cast<float>(p.z() - o.min_height_m) + 1e-3f;
    sc.grid(ring, sector) = std::max(sc.grid(ring, sector), value);
  }
  sc.ring_key.resize(o.rings);
  for (int i = 0; i < o.rings; ++i)
    sc.ring_key(i) = static_cast<float>((sc.grid.row(i).array() > 0).count()) / static_cast<float>(o.sectors);
  return sc;
}

ScanContextMatch CompareScanContexts(const ScanContext& a, const ScanContext& b) {
  ScanContextMatch best;
  const int sectors = static_cast<int>(a.grid.cols());
  if (b.grid.cols() != sectors || b.grid.rows() != a.grid.rows()) throw Error("scan context: different shapes");
  // Column norms once; a column of b at sector j sits at sector j + k of a
  // when b's frame is turned by k sectors against a's.
  Eigen::VectorXf na = a.grid.colwise().norm(), nb = b.grid.colwise().norm();
  for (int k = 0; k < sectors; ++k) {
    double sum = 0;
    int used = 0;
    for (int j = 0; j < sectors; ++j) {
      const int ja = (j + k) % sectors;
      if (na(ja) == 0 || nb(j) == 0) continue;
      sum += 1.0 - a.grid.col(ja).dot(b.grid.col(j)) / (na(ja) * nb(j));
      ++used;
    }
    if (used == 0) continue;
    const double d = sum / used;
    if (d < best.distance) {
      best.distance = d;
      best.yaw = 2 * M_PI * k / sectors;
      if (best.yaw > M_PI) best.yaw -= 2 * M_PI;
    }
  }
  return best;
}

double RingKeyDistance(const ScanContext& a, const ScanContext& b) {
  return (a.ring_key - b.ring_key).cwiseAbs().mean();
}

}  // namespace locforge::lidar

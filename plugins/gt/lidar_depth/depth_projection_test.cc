#include "depth_projection.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "locforge/error.h"

namespace locforge::depth {
namespace {

// A closed room [-5, 5] x [-4, 4] x [0, 3] m with a square pillar
// [2, 2.4] x [-0.2, 0.2] x [0, 3], its surfaces sampled every `step` m (a
// LiDAR map of 5 cm voxels), and the exact depth of any ray by ray casting.
struct Room {
  Eigen::Vector3d lo{-5, -4, 0}, hi{5, 4, 3};
  Eigen::Vector3d pillar_lo{2, -0.2, 0}, pillar_hi{2.4, 0.2, 3};

  std::vector<Eigen::Vector3f> Sample(double step) const {
    std::vector<Eigen::Vector3f> pts;
    auto box_surface = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
      for (int axis = 0; axis < 3; ++axis)
        for (double side : {a[axis], b[axis]}) {
          const int i = (axis + 1) % 3, j = (axis + 2) % 3;
          for (double u = a[i] + step / 2; u < b[i]; u += step)
            for (double v = a[j] + step / 2; v < b[j]; v += step) {
              Eigen::Vector3d p;
              p[axis] = side;
              p[i] = u;
              p[j] = v;
              pts.push_back(p.cast<float>());
            }
        }
    };
    box_surface(lo, hi);
    box_surface(pillar_lo, pillar_hi);
    return pts;
  }
  // Distance along d (unit) from o inside the room to the first surface.
  double Cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    double t = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 3; ++k)
      if (d[k] != 0) t = std::min(t, ((d[k] > 0 ? hi[k] : lo[k]) - o[k]) / d[k]);
    double t0 = 0, t1 = std::numeric_limits<double>::infinity();  // slabs of the pillar
    for (int k = 0; k < 3; ++k) {
      if (d[k] == 0) {
        if (o[k] < pillar_lo[k] || o[k] > pillar_hi[k]) return t;
        continue;
      }
      double a = (pillar_lo[k] - o[k]) / d[k], b = (pillar_hi[k] - o[k]) / d[k];
      if (a > b) std::swap(a, b);
      t0 = std::max(t0, a);
      t1 = std::min(t1, b);
    }
    return t0 <= t1 ? std::min(t, t0) : t;
  }
};

TEST(ProjectMap, MatchesRayCastDepthAndHidesWhatThePillarOccludes) {
  const Room room;
  const MapIndex map(room.Sample(0.05));
  Camera camera;
  camera.model = CameraModelId::kPinhole;
  camera.width = 320;
  camera.height = 240;
  camera.params = {200, 200, 160, 120};
  // Camera at (0, 0.1, 1.5) looking along +x (camera z = world x, camera y = -world z), turned 10 deg.
  Eigen::Matrix3d R_wc;
  R_wc << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  R_wc = Eigen::AngleAxisd(10 * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix() * R_wc;
  const Pose T_world_camera(Eigen::Quaterniond(R_wc), Eigen::Vector3d(0, 0.1, 1.5));
  const DepthMap depth = ProjectMap(map, camera, T_world_camera.Inverse());
  DepthMap exact = depth;
  int on_pillar = 0, pillar_right = 0;
  for (int y = 0; y < camera.height; ++y)
    for (int x = 0; x < camera.width; ++x) {
      const Eigen::Vector3d ray = camera.Unproject({x + 0.5, y + 0.5});  // z = 1
      const Eigen::Vector3d d = R_wc * ray.normalized();
      const double s = room.Cast(T_world_camera.t, d);
      exact.z[y * camera.width + x] = static_cast<float>(s / ray.norm());  // z of the hit
      const Eigen::Vector3d hit = T_world_camera.t + s * d;
      if (hit.x() < 2.45 && std::abs(hit.y()) < 0.25 && hit.x() > 1.95) {
        ++on_pillar;
        pillar_right += std::abs(depth.z[y * camera.width + x] - exact.z[y * camera.width + x]) < 0.05;
      }
    }
  DepthErrors e;
  AccumulateDepthErrors(depth, exact, nullptr, 0.05, &e);
  if (std::getenv("LOCFORGE_DEBUG_DEPTH"))
    for (int y = 0; y < camera.height; y += 8) {
      for (int x = 0; x < camera.width; x += 4) {
        const double err = std::abs(depth.z[y * camera.width + x] - exact.z[y * camera.width + x]);
        std::printf("%c", err < 0.01 ? '.' : err < 0.05 ? 'o' : 'X');
      }
      std::printf("\n");
    }
  const double median = e.Quantile(0.5), p90 = e.Quantile(0.9), coverage = e.Coverage();
  std::printf("room: coverage %.3f, median %.4f m, p90 %.4f m, pillar pixels right %d / %d\n", coverage, median, p90,
              pillar_right, on_pillar);
  EXPECT_GT(coverage, 0.98);
  EXPECT_LT(median, 0.005);
  EXPECT_LT(p90, 0.06);  // 4.75 cm: grazing floor, ceiling and pillar sides, room corners
  // The pillar hides the wall behind it: its pixels carry the pillar's depth.
  ASSERT_GT(on_pillar, 500);
  EXPECT_GT(pillar_right, 0.97 * on_pillar);
}

TEST(DepthErrors, HistogramQuantilesAndFractions) {
  DepthErrors e;
  for (int i = 1; i <= 100; ++i) e.Add(0.001 * i);  // 1 .. 100 mm
  e.Add(7.0);                                        // beyond the histogram
  EXPECT_NEAR(e.Quantile(0.5), 0.051, 0.001);
  EXPECT_NEAR(e.FractionWithin(0.05), 50.0 / 101, 0.011);
  EXPECT_TRUE(std::isinf(e.Quantile(1.0)));
}

TEST(DepthFiles, RoundTripAndSizeCheck) {
  DepthMap d;
  d.width = 3;
  d.height = 2;
  d.z = {0, 1.5f, 2.25f, 0, 30, 0.001f};
  const std::string bytes = EncodeDepth(d);
  ASSERT_EQ(bytes.size(), 24u);
  EXPECT_EQ(DecodeDepth(bytes, 3, 2, "x.depth").z, d.z);
  EXPECT_THROW(DecodeDepth(bytes, 4, 2, "x.depth"), InputError);
}

}  // namespace
}  // namespace locforge::depth

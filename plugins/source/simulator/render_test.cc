#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "camera_rig.h"
#include "render.h"

namespace locforge::sim {
namespace {

// A 16 x 12 m room with a marker disc (radius 0.35 m) on a panel facing -x.
struct MarkerRoom {
  Scene scene;
  Crowd crowd;
  TextureLibrary textures{256};
  std::unique_ptr<World> world;
  Eigen::Vector3d marker_center{8.0, 0.9, 1.35};

  explicit MarkerRoom(Crowd people = {}) : crowd(std::move(people)) {
    SceneSpec spec;
    spec.x0 = -4;
    spec.x1 = 12;
    spec.y0 = -6;
    spec.y1 = 6;
    spec.walk.nodes = {{0, 0}, {4, 0}};
    spec.walk.edges = {{0, 1}};
    PanelSpec marker;
    marker.center = marker_center;
    marker.yaw_deg = 180;
    marker.material = {"marker"};
    spec.panels.push_back(marker);
    scene = BuildScene(spec);
    world = std::make_unique<World>(scene, crowd, &textures, 0);
  }
};

// Intensity-weighted centroid of the dark blob around `guess` (pixel-centre convention).
Eigen::Vector2d DarkCentroid(const RenderedImage& img, const Eigen::Vector2d& guess, int radius) {
  const auto gray = [&](int x, int y) {
    const uint8_t* p = &img.rgb[(size_t(y) * img.width + x) * 3];
    return (p[0] + p[1] + p[2]) / 3.0;
  };
  const int cx = static_cast<int>(guess.x()), cy = static_cast<int>(guess.y());
  double bg = 0;
  int n = 0;
  for (int y = cy - radius; y <= cy + radius; ++y)
    for (int x = cx - radius; x <= cx + radius; ++x)
      if (std::abs(x - cx) == radius || std::abs(y - cy) == radius) bg += gray(x, y), ++n;
  bg /= n;
  double sw = 0, sx = 0, sy = 0;
  for (int y = cy - radius; y <= cy + radius; ++y)
    for (int x = cx - radius; x <= cx + radius; ++x) {
      const double w = std::max(0.0, bg - gray(x, y) - 8);  // ignore noise around the background
      sw += w;
      sx += w * (x + 0.5);
      sy += w * (y + 0.5);
    }
  return {sx / sw, sy / sw};
}

TEST(Render, MarkerLandsAtItsProjectedPixelInEveryRigCamera) {
  MarkerRoom room;
  RigOptions ro;
  ro.image_scale = 0.125;
  const Rig rig = MakeRig(ro, 1);
  ASSERT_EQ(rig.cameras.size(), 10u);
  double worst = 0;
  for (size_t i = 0; i < rig.cameras.size(); ++i) {
    const CameraOptions& cam = rig.cameras[i];
    // Turn the platform so this camera looks roughly along +x at the marker.
    const Eigen::Vector3d axis = cam.T_platform_camera.R().col(2);
    const double yaw = -std::atan2(axis.y(), axis.x()) + 0.05 * (static_cast<int>(i) - 4);
    const Pose T_world_platform(Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())),
                                {0.3, -0.2, 0.1});
    const Pose T_world_camera = T_world_platform * cam.T_platform_camera;
    const Eigen::Vector3d p_cam = T_world_camera.Inverse() * room.marker_center;
    ASSERT_GT(p_cam.z(), 0);
    const Eigen::Vector2d expected = cam.intrinsics.Project(p_cam);
    RenderedImage img;
    RenderOptions opt;
    opt.noise_seed = i;
    Render(*room.world, {}, cam.intrinsics, T_world_camera, opt, &img);
    const int radius = static_cast<int>(0.35 / p_cam.z() * cam.intrinsics.fx * 1.6) + 3;
    ASSERT_GT(expected.x(), radius);
    ASSERT_LT(expected.x(), img.width - radius);
    ASSERT_GT(expected.y(), radius);
    ASSERT_LT(expected.y(), img.height - radius);
    const Eigen::Vector2d measured = DarkCentroid(img, expected, radius);
    const double err = (measured - expected).norm();
    worst = std::max(worst, err);
    EXPECT_LT(err, 0.5) << cam.id << " expected " << expected.transpose() << " measured " << measured.transpose();
  }
  std::printf("marker centroid vs projection: worst error %.3f px over 10 cameras\n", worst);
}

TEST(Render, PersonMaskCoversThePersonOnly) {
  Person p;
  p.path = {{4, 0}};
  p.speed = 0;
  p.height = 1.8;
  MarkerRoom room(Crowd({p}));
  const PinholeCamera cam = PinholeCamera::FromFov(200, 160, 79.4, 63);
  const Pose T_world_camera = Pose(Eigen::Quaterniond::Identity(), {0, 0, 1.5}) * CameraMount(0, 0, {0, 0, 0});
  RenderedImage img;
  Render(*room.world, room.crowd.At(0), cam, T_world_camera, {}, &img);
  const Eigen::Vector2d body = cam.Project(T_world_camera.Inverse() * Eigen::Vector3d(4, 0, 1.0));
  const Eigen::Vector2d above = cam.Project(T_world_camera.Inverse() * Eigen::Vector3d(4, 0, 2.3));
  EXPECT_EQ(img.person_mask[int(body.y()) * img.width + int(body.x())], 255);
  EXPECT_EQ(img.person_mask[int(above.y()) * img.width + int(above.x())], 0);
  // Expected silhouette: (2 r / 4 m * fx) x (1.8 m / 4 m * fy) pixels, roughly.
  const double expected = (2 * 0.25 / 4 * cam.fx) * (1.8 / 4 * cam.fy) / (200.0 * 160.0);
  EXPECT_NEAR(img.PersonFraction(), expected, 0.25 * expected);
}

TEST(Render, DepthIsTheZOfTheNearestSurface) {
  Person p;
  p.path = {{4, -0.8}};
  p.speed = 0;
  p.height = 1.8;
  MarkerRoom room(Crowd({p}));
  const PinholeCamera cam = PinholeCamera::FromFov(200, 160, 79.4, 63);
  const Pose T_world_camera = Pose(Eigen::Quaterniond::Identity(), {0, 0, 1.5}) * CameraMount(0, 0, {0, 0, 0});
  RenderedImage img;
  Render(*room.world, room.crowd.At(0), cam, T_world_camera, {}, &img);
  ASSERT_EQ(img.depth.size(), size_t(img.width) * img.height);
  // The pixel of the marker's centre: its depth back-projects onto the marker
  // panel (x = 8, the panel faces -x), whatever the pixel's off-axis angle.
  const Eigen::Vector2d m = cam.Project(T_world_camera.Inverse() * room.marker_center);
  const int mi = int(m.y()) * img.width + int(m.x());
  const Eigen::Vector3d ray = cam.Ray(int(m.x()) + 0.5, int(m.y()) + 0.5);
  const Eigen::Vector3d X = T_world_camera * (ray / ray.z() * img.depth[mi]);
  EXPECT_NEAR(X.x(), room.marker_center.x(), 0.02) << X.transpose();
  EXPECT_LT((X - room.marker_center).norm(), 0.35);
  // The person (a cylinder of radius 0.25 m at 4 m) is nearer than the wall behind.
  const Eigen::Vector2d b = cam.Project(T_world_camera.Inverse() * Eigen::Vector3d(4, -0.8, 1.0));
  const int bi = int(b.y()) * img.width + int(b.x());
  ASSERT_EQ(img.person_mask[bi], 255);
  const Eigen::Vector3d rb = cam.Ray(int(b.x()) + 0.5, int(b.y()) + 0.5);
  const Eigen::Vector3d B = T_world_camera * (rb / rb.z() * img.depth[bi]);
  EXPECT_NEAR(std::hypot(B.x() - 4, B.y() + 0.8), 0.25, 0.01) << B.transpose();  // on the cylinder
}

TEST(Render, DeterministicAndIndependentOfTheRowSplit) {
  MarkerRoom room;
  const PinholeCamera cam = PinholeCamera::FromFov(120, 90, 79.4, 63);
  const Pose T = CameraMount(10, 5, {0, 0, 1.5});
  RenderOptions o;
  o.noise_seed = 42;
  RenderedImage whole, split;
  Render(*room.world, {}, cam, T, o, &whole);
  Render(*room.world, {}, cam, T, o, &split, 0, 40);
  Render(*room.world, {}, cam, T, o, &split, 40, 90);
  EXPECT_EQ(whole.rgb, split.rgb);
  // Exposure/gain scale the image.
  RenderOptions bright = o;
  bright.gain = 1.5;
  bright.noise_sigma = 0;
  RenderedImage b, d;
  o.noise_sigma = 0;
  Render(*room.world, {}, cam, T, o, &d);
  Render(*room.world, {}, cam, T, bright, &b);
  double sd = 0, sb = 0;
  for (size_t i = 0; i < d.rgb.size(); ++i)
    if (d.rgb[i] < 150) sd += d.rgb[i], sb += b.rgb[i];
  EXPECT_NEAR(sb / sd, 1.5, 0.05);
}

TEST(Render, RigGeometryFollowsThePaper) {
  const Rig rig = MakeRig(RigOptions{}, 0);
  const CameraOptions& ind = rig.cameras[0];
  EXPECT_EQ(ind.intrinsics.width, 2592);
  EXPECT_EQ(ind.intrinsics.height, 2048);
  EXPECT_NEAR(2 * std::atan(1296 / ind.intrinsics.fx) * 180 / M_PI, 79.4, 1e-9);
  // 60 degree spacing, 10 degrees up.
  for (int i = 0; i < 6; ++i) {
    const Eigen::Vector3d f = rig.cameras[i].T_platform_camera.R().col(2);
    EXPECT_NEAR(std::asin(f.z()) * 180 / M_PI, 10, 1e-9);
    EXPECT_NEAR(std::remainder(std::atan2(f.y(), f.x()) * 180 / M_PI - 60 * i, 360), 0, 1e-9);
  }
  const CameraOptions& phone = rig.cameras[6];
  EXPECT_EQ(phone.intrinsics.width, 2160);
  EXPECT_EQ(phone.intrinsics.height, 2880);
  EXPECT_NEAR(2 * std::atan(1800 / phone.intrinsics.fx) * 180 / M_PI, 77, 1e-9);
  EXPECT_GT(phone.T_platform_camera.t.z(), ind.T_platform_camera.t.z());
  // Clocks: captures at the nominal rate, stamps offset from the truth by a few ms.
  const auto caps = CaptureTimes(ind, 10, 3);
  EXPECT_NEAR(caps.size(), 25, 1);
  for (const auto& c : caps) EXPECT_LT(std::abs(c.stamp - c.true_time), 0.03);
}

}  // namespace
}  // namespace locforge::sim

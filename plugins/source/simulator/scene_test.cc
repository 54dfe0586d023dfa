#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <set>

#include "locforge/error.h"
#include "raycast.h"
#include "scene.h"
#include "testing.h"

namespace locforge::sim {
namespace {

SceneSpec SmallFloor() {
  FloorOptions o;
  o.blocks_x = 3;
  o.blocks_y = 2;
  return GenerateFloor(o, 7);
}

TEST(Scene, GeneratedFloorHasEveryHardCase) {
  const SceneSpec s = SmallFloor();
  std::set<std::string> kinds;
  for (const auto& p : s.panels) kinds.insert(p.material.texture.substr(0, p.material.texture.find(':')));
  for (const char* k : {"poster", "signage", "glossy", "plain", "shopfront"}) EXPECT_TRUE(kinds.count(k)) << k;
  EXPECT_EQ(s.holes.size(), 1u);
  EXPECT_EQ(s.walk.nodes.size(), 12u);
  EXPECT_EQ(s.walk.edges.size(), 17u);
  // The twin blocks carry the same panels, shifted.
  int twins = 0;
  for (size_t i = 0; i < s.panels.size(); ++i)
    for (size_t j = i + 1; j < s.panels.size(); ++j)
      if (s.panels[i].material == s.panels[j].material && s.panels[i].material.texture.rfind("poster", 0) == 0)
        ++twins;
  EXPECT_GT(twins, 0);
  for (const auto& b : s.boxes) {
    EXPECT_GE(b.center.x() - b.size.x() / 2, s.x0 - 1e-9);
    EXPECT_LE(b.center.x() + b.size.x() / 2, s.x1 + 1e-9);
  }
}

TEST(Scene, GeneratorIsDeterministicAndSeedDependent) {
  FloorOptions o;
  const Scene a = BuildScene(GenerateFloor(o, 1)), b = BuildScene(GenerateFloor(o, 1));
  const Scene c = BuildScene(GenerateFloor(o, 2));
  ASSERT_EQ(a.quads.size(), b.quads.size());
  for (size_t i = 0; i < a.quads.size(); ++i) EXPECT_EQ(a.quads[i].origin, b.quads[i].origin);
  // Another seed decorates the floor differently.
  std::vector<std::string> ma, mc;
  for (const auto& m : a.materials) ma.push_back(m.texture);
  for (const auto& m : c.materials) mc.push_back(m.texture);
  EXPECT_NE(ma, mc);
}

TEST(Scene, VerticalRaysHitFloorCeilingAndHoleBottom) {
  const SceneSpec spec = SmallFloor();
  const Scene scene = BuildScene(spec);
  Crowd crowd;
  TextureLibrary textures(64);
  World world(scene, crowd, &textures, 0);
  const Eigen::Vector2d p = spec.walk.nodes[0];
  Hit up, down;
  ASSERT_TRUE(world.Cast({p.x(), p.y(), 1.0}, {0, 0, 1}, {}, &up));
  EXPECT_NEAR(up.t, spec.height - 1.0, 1e-9);
  EXPECT_NEAR(up.normal.z(), -1, 1e-12);
  ASSERT_TRUE(world.Cast({p.x(), p.y(), 1.0}, {0, 0, -1}, {}, &down));
  EXPECT_NEAR(down.t, 1.0, 1e-9);
  const HoleSpec& h = spec.holes[0];
  Hit well;
  ASSERT_TRUE(world.Cast({0.5 * (h.x0 + h.x1), 0.5 * (h.y0 + h.y1), 1.0}, {0, 0, -1}, {}, &well));
  EXPECT_NEAR(well.t, 1.0 + spec.lower_level_depth, 1e-9);
}

TEST(Scene, BvhMatchesBruteForce) {
  const Scene scene = BuildScene(SmallFloor());
  QuadBvh bvh(scene.quads);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> ux(scene.spec.x0, scene.spec.x1), uy(scene.spec.y0, scene.spec.y1),
      uz(0.1, 3.9), un(-1, 1);
  int hits = 0;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector3d o(ux(rng), uy(rng), uz(rng));
    const Eigen::Vector3d d = Eigen::Vector3d(un(rng), un(rng), un(rng)).normalized();
    Hit fast, slow;
    bvh.Intersect(o, d, 1e-6, &fast);
    for (size_t q = 0; q < scene.quads.size(); ++q)
      if (IntersectQuad(scene.quads[q], o, d, 1e-6, &slow)) slow.quad = static_cast<int>(q);
    ASSERT_EQ(fast.quad >= 0, slow.quad >= 0);
    if (slow.quad >= 0) {
      EXPECT_NEAR(fast.t, slow.t, 1e-9);
      ++hits;
    }
  }
  EXPECT_GT(hits, 2900);  // the floor is closed: nearly every ray hits something
}

TEST(Scene, CylinderHitsSideAndTop) {
  Cylinder c{{0, 0}, 0.5, 0, 2, 3};
  Hit side;
  ASSERT_TRUE(IntersectCylinder(c, {-3, 0, 1}, {1, 0, 0}, 0, &side));
  EXPECT_NEAR(side.t, 2.5, 1e-12);
  EXPECT_EQ(side.person, 3);
  EXPECT_NEAR(side.normal.x(), -1, 1e-12);
  Hit top;
  ASSERT_TRUE(IntersectCylinder(c, {0.1, 0, 5}, {0, 0, -1}, 0, &top));
  EXPECT_NEAR(top.t, 3, 1e-12);
  Hit miss;
  EXPECT_FALSE(IntersectCylinder(c, {-3, 0, 2.5}, {1, 0, 0}, 0, &miss));
}

TEST(Scene, LoadsYamlFloorPlan) {
  const auto dir = locforge::testing::MakeTempDir("sim_scene");
  const auto file = dir / "floor.yaml";
  std::ofstream(file) << "extent: [0, 0, 12, 8]\nheight: 3.5\nfloor: tiles:2\n"
                         "wall: {texture: glossy:1, glossy: true}\n"
                         "boxes:\n  - {center: [6, 4, 1.75], size: [2, 2, 3.5], sides: noise:1}\n"
                         "panels:\n  - {center: [0.02, 4, 1.5], yaw_deg: 0, width: 2, height: 1.5, material: poster:3}\n"
                         "holes: [[1, 1, 2, 2]]\n"
                         "walk: {nodes: [[2, 4], [10, 4]], edges: [[0, 1]]}\n";
  const SceneSpec s = LoadSceneSpec(file);
  EXPECT_DOUBLE_EQ(s.x1, 12);
  EXPECT_DOUBLE_EQ(s.height, 3.5);
  EXPECT_TRUE(s.wall.glossy);
  ASSERT_EQ(s.boxes.size(), 1u);
  EXPECT_EQ(s.boxes[0].sides[0].texture, "noise:1");
  ASSERT_EQ(s.panels.size(), 1u);
  EXPECT_EQ(s.holes.size(), 1u);
  EXPECT_EQ(s.walk.edges.size(), 1u);
  const Scene scene = BuildScene(s);
  EXPECT_GT(scene.quads.size(), 10u);
}

TEST(Scene, BadYamlNamesFileLineAndField) {
  const auto dir = locforge::testing::MakeTempDir("sim_scene_bad");
  const auto file = dir / "floor.yaml";
  std::ofstream(file) << "extent: [0, 0, 12, 8]\nboxes:\n  - {center: [6, 4], size: [2, 2, 3]}\n"
                         "walk: {nodes: [[2, 4], [10, 4]], edges: [[0, 1]]}\n";
  try {
    LoadSceneSpec(file);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("floor.yaml:3"), std::string::npos) << m;
    EXPECT_NE(m.find("boxes[0].center"), std::string::npos) << m;
  }
  std::ofstream(file) << "extent: [0, 0, 12, 8]\nwalk: {nodes: [[2, 4], [10, 4]], edges: [[0, 5]]}\n";
  EXPECT_THROW(LoadSceneSpec(file), InputError);
  EXPECT_THROW(LoadSceneSpec(dir / "missing.yaml"), InputError);
}

}  // namespace
}  // namespace locforge::sim

namespace locforge::sim {
namespace {

TEST(Scene, PanelsHangBetweenFloorAndCeiling) {
  FloorOptions o;
  o.blocks_x = 3;
  const SceneSpec s = GenerateFloor(o, 5);
  for (const auto& p : s.panels) {
    EXPECT_GE(p.center.z() - p.height / 2, -1e-9) << p.material.texture;
    EXPECT_LE(p.center.z() + p.height / 2, s.height) << p.material.texture;
  }
}

}  // namespace
}  // namespace locforge::sim

namespace locforge::sim {
namespace {

TEST(Scene, KiosksMoveBetweenDays) {
  FloorOptions o;
  o.blocks_x = 3;
  o.blocks_y = 2;
  const Scene scene = BuildScene(GenerateFloor(o, 2));
  Crowd crowd;
  TextureLibrary textures(32);
  std::set<size_t> counts;
  for (int day = 0; day < 6; ++day) counts.insert(World(scene, crowd, &textures, day).quads().size());
  EXPECT_GT(counts.size(), 1u);  // the set of surfaces changes from day to day
  EXPECT_EQ(World(scene, crowd, &textures, 0).quads().size(), World(scene, crowd, &textures, 32).quads().size());
}

TEST(Scene, YamlDaysSelectWhenAnObjectExists) {
  const auto dir = locforge::testing::MakeTempDir("sim_scene_days");
  const auto file = dir / "floor.yaml";
  std::ofstream(file) << "extent: [0, 0, 12, 8]\n"
                         "panels:\n  - {center: [6, 4, 1.5], width: 1, height: 1, material: poster:1, days: [1, 3]}\n"
                         "walk: {nodes: [[2, 4], [10, 4]], edges: [[0, 1]]}\n";
  const Scene scene = BuildScene(LoadSceneSpec(file));
  Crowd crowd;
  TextureLibrary textures(32);
  EXPECT_EQ(World(scene, crowd, &textures, 1).quads().size(), World(scene, crowd, &textures, 0).quads().size() + 1);
  EXPECT_EQ(World(scene, crowd, &textures, 3).quads().size(), World(scene, crowd, &textures, 1).quads().size());
  std::ofstream(file) << "extent: [0, 0, 12, 8]\n"
                         "panels:\n  - {center: [6, 4, 1.5], material: poster:1, days: [-1]}\n"
                         "walk: {nodes: [[2, 4], [10, 4]], edges: [[0, 1]]}\n";
  EXPECT_THROW(LoadSceneSpec(file), InputError);
}

}  // namespace
}  // namespace locforge::sim

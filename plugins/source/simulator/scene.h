// The static scene: a floor of a mall or metro station made of textured
// rectangles (quads). A SceneSpec is the high-level floor plan (boxes, wall
// panels, floor openings and the graph of walkable corridor centrelines); it is
// read from YAML or generated from a seed, then compiled into quads.
//
// World frame: x east, y north, z up, metres; the floor is z = 0.
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_SCENE_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_SCENE_H_

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace locforge::sim {

// A surface look. `texture` is a texture key (texture.h), e.g. "bricks:2".
struct Material {
  std::string texture;
  bool glossy = false;  // adds a view-dependent specular highlight (reflective panels)
  bool operator==(const Material& o) const { return texture == o.texture && glossy == o.glossy; }
};

// A rectangle: origin + a*u_edge + b*v_edge for a, b in [0, 1].
struct Quad {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d u_edge = Eigen::Vector3d::UnitX();
  Eigen::Vector3d v_edge = Eigen::Vector3d::UnitY();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit, along u_edge x v_edge
  int material = 0;
  // Texture period in metres along u and v; 0 stretches the texture once over the quad.
  double tile_m = 0;
  // Added to the metric (u, v) before tiling, so split floors keep a continuous texture.
  Eigen::Vector2d tex_offset = Eigen::Vector2d::Zero();
  // Days the surface exists (moved objects): bit (day % 32); 0 = every day.
  uint32_t days = 0;
  bool PresentOn(int day) const { return days == 0 || ((days >> (day % 32)) & 1u) != 0; }

  double width() const { return u_edge.norm(); }
  double height() const { return v_edge.norm(); }
};

// An upright box standing on z = center.z - size.z / 2.
struct BoxSpec {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d size = Eigen::Vector3d::Ones();
  double yaw_deg = 0;
  // Side materials in the order +x, +y, -x, -y of the box frame; one entry is used for all.
  std::vector<Material> sides;
  Material top;             // empty texture: no top face (e.g. boxes reaching the ceiling)
  double tile_m = 2.0;      // texture period of the sides
  uint32_t days = 0;        // present on days with bit (day % 32) set; 0 = every day
};

// A vertical rectangle (poster, shop window, signage, glossy panel, temporary
// wall, marker) facing direction yaw (its normal is (cos yaw, sin yaw, 0)).
struct PanelSpec {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double yaw_deg = 0;
  double width = 1, height = 1;
  Material material;
  double tile_m = 0;  // 0: stretched
  uint32_t days = 0;  // present on days with bit (day % 32) set; 0 = every day
};

// A rectangular opening in the floor (stairs/escalator well) onto a lower level.
struct HoleSpec {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

// Corridor centrelines: where the platform and the people walk.
struct WalkGraph {
  std::vector<Eigen::Vector2d> nodes;
  std::vector<std::pair<int, int>> edges;
  std::vector<std::vector<int>> Neighbours() const;
  int Nearest(const Eigen::Vector2d& p) const;
};

struct SceneSpec {
  double x0 = 0, y0 = 0, x1 = 20, y1 = 10;  // floor extent; perimeter walls on its border
  double height = 4.0;                        // ceiling height
  double lower_level_depth = 5.0;             // depth of the level seen through holes
  Material floor{"tiles:0"}, ceiling{"ceiling:0"}, wall{"bricks:0"}, lower_floor{"tiles:1"};
  double floor_tile_m = 2.0, ceiling_tile_m = 2.4, wall_tile_m = 3.0;
  std::vector<BoxSpec> boxes;
  std::vector<PanelSpec> panels;
  std::vector<HoleSpec> holes;
  WalkGraph walk;
  int start_node = 0;         // sequences start near this node
  double query_split_x = 10;  // queries: validation area x < split, test area x >= split
};

// Options of the seeded floor generator: a grid of shop blocks separated by corridors.
struct FloorOptions {
  int blocks_x = 2;             // shop blocks along x
  int blocks_y = 1;             // shop blocks along y
  double block_x = 6.0;         // block size along x (m)
  double block_y = 6.0;         // block size along y (m)
  double corridor = 4.5;        // corridor width (m)
  double height = 4.0;          // ceiling height (m)
  bool Check(std::string* why) const;
};

// Generates a floor plan with all of the paper's hard cases: identical blocks,
// textureless temporary walls, glossy panels, signage, pillars, turnstiles,
// kiosks that move between days, and (when there are at least 3 blocks along
// x) one block replaced by a floor opening.
SceneSpec GenerateFloor(const FloorOptions& options, uint64_t seed);

// Reads a floor plan from YAML (format in README.md). Throws InputError naming
// the file, line and field on bad input.
SceneSpec LoadSceneSpec(const std::filesystem::path& yaml_file);

// The compiled scene: quads and their materials.
struct Scene {
  SceneSpec spec;
  std::vector<Quad> quads;
  std::vector<Material> materials;
  int AddMaterial(const Material& m);
};

Scene BuildScene(const SceneSpec& spec);

// Adds the quads of one box / panel to a scene (used by BuildScene and by tests).
void AddBox(const BoxSpec& box, Scene* scene);
void AddPanel(const PanelSpec& panel, Scene* scene);

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_SCENE_H_

#include "scene.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include "locforge/error.h"
#include "locforge/params.h"

namespace locforge::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

Quad MakeQuad(const Eigen::Vector3d& origin, const Eigen::Vector3d& u, const Eigen::Vector3d& v,
              int material, double tile_m) {
  Quad q;
  q.origin = origin;
  q.u_edge = u;
  q.v_edge = v;
  q.normal = u.cross(v).normalized();
  q.material = material;
  q.tile_m = tile_m;
  return q;
}

// A vertical quad of the given width/height centred at `center`, facing `normal`.
Quad VerticalQuad(const Eigen::Vector3d& center, const Eigen::Vector3d& normal, double width,
                  double height, int material, double tile_m) {
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d u = up.cross(normal).normalized() * width;
  const Eigen::Vector3d v = up * height;
  return MakeQuad(center - 0.5 * u - 0.5 * v, u, v, material, tile_m);
}

// Horizontal rectangle [x0,x1]x[y0,y1] at height z, facing up or down; its
// texture is anchored to world x/y so neighbouring pieces tile seamlessly.
Quad HorizontalQuad(double x0, double y0, double x1, double y1, double z, bool up, int material,
                    double tile_m) {
  Quad q;
  if (up) {
    q = MakeQuad({x0, y0, z}, {x1 - x0, 0, 0}, {0, y1 - y0, 0}, material, tile_m);
    q.tex_offset = {x0, y0};
  } else {
    q = MakeQuad({x0, y1, z}, {x1 - x0, 0, 0}, {0, y0 - y1, 0}, material, tile_m);
    q.tex_offset = {x0, -y1};
  }
  return q;
}

bool InsideHole(const SceneSpec& s, double x, double y) {
  for (const auto& h : s.holes)
    if (x > h.x0 && x < h.x1 && y > h.y0 && y < h.y1) return true;
  return false;
}

// The floor minus the holes, as a grid of rectangles cut at every hole edge.
void AddFloor(const SceneSpec& s, int material, Scene* scene) {
  std::set<double> xs{s.x0, s.x1}, ys{s.y0, s.y1};
  for (const auto& h : s.holes) {
    xs.insert({h.x0, h.x1});
    ys.insert({h.y0, h.y1});
  }
  const std::vector<double> vx(xs.begin(), xs.end()), vy(ys.begin(), ys.end());
  for (size_t i = 0; i + 1 < vx.size(); ++i)
    for (size_t j = 0; j + 1 < vy.size(); ++j) {
      if (InsideHole(s, 0.5 * (vx[i] + vx[i + 1]), 0.5 * (vy[j] + vy[j + 1]))) continue;
      scene->quads.push_back(
          HorizontalQuad(vx[i], vy[j], vx[i + 1], vy[j + 1], 0, true, material, s.floor_tile_m));
    }
}

void AddHole(const SceneSpec& s, const HoleSpec& h, int wall, int lower_floor, Scene* scene) {
  const double d = s.lower_level_depth;
  scene->quads.push_back(HorizontalQuad(h.x0, h.y0, h.x1, h.y1, -d, true, lower_floor,
                                        s.floor_tile_m));
  const double cx = 0.5 * (h.x0 + h.x1), cy = 0.5 * (h.y0 + h.y1);
  const double w = h.x1 - h.x0, l = h.y1 - h.y0;
  // Shaft walls, facing into the shaft.
  scene->quads.push_back(VerticalQuad({h.x0, cy, -d / 2}, {1, 0, 0}, l, d, wall, s.wall_tile_m));
  scene->quads.push_back(VerticalQuad({h.x1, cy, -d / 2}, {-1, 0, 0}, l, d, wall, s.wall_tile_m));
  scene->quads.push_back(VerticalQuad({cx, h.y0, -d / 2}, {0, 1, 0}, w, d, wall, s.wall_tile_m));
  scene->quads.push_back(VerticalQuad({cx, h.y1, -d / 2}, {0, -1, 0}, w, d, wall, s.wall_tile_m));
}

}  // namespace

std::vector<std::vector<int>> WalkGraph::Neighbours() const {
  std::vector<std::vector<int>> out(nodes.size());
  for (const auto& [a, b] : edges) {
    out[a].push_back(b);
    out[b].push_back(a);
  }
  return out;
}

int WalkGraph::Nearest(const Eigen::Vector2d& p) const {
  int best = -1;
  double best_d = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < nodes.size(); ++i) {
    const double d = (nodes[i] - p).squaredNorm();
    if (d < best_d) best_d = d, best = static_cast<int>(i);
  }
  return best;
}

int Scene::AddMaterial(const Material& m) {
  for (size_t i = 0; i < materials.size(); ++i)
    if (materials[i] == m) return static_cast<int>(i);
  materials.push_back(m);
  return static_cast<int>(materials.size()) - 1;
}

void AddBox(const BoxSpec& box, Scene* scene) {
  const double yaw = DegreesToRadians(box.yaw_deg);
  const Eigen::Vector3d ax(std::cos(yaw), std::sin(yaw), 0), ay(-std::sin(yaw), std::cos(yaw), 0);
  const Eigen::Vector3d half = 0.5 * box.size;
  const Eigen::Vector3d normals[4] = {ax, ay, -ax, -ay};
  const double offsets[4] = {half.x(), half.y(), half.x(), half.y()};
  const double widths[4] = {box.size.y(), box.size.x(), box.size.y(), box.size.x()};
  for (int side = 0; side < 4; ++side) {
    const Material& m = box.sides.empty() ? Material{"plain:0"}
                        : box.sides.size() == 1 ? box.sides[0]
                                                : box.sides[std::min<size_t>(side, box.sides.size() - 1)];
    scene->quads.push_back(VerticalQuad(box.center + normals[side] * offsets[side], normals[side],
                                        widths[side], box.size.z(), scene->AddMaterial(m),
                                        box.tile_m));
    scene->quads.back().days = box.days;
  }
  if (!box.top.texture.empty()) {
    const Eigen::Vector3d c = box.center + Eigen::Vector3d(0, 0, half.z());
    const Eigen::Vector3d u = ax * box.size.x(), v = ay * box.size.y();
    scene->quads.push_back(
        MakeQuad(c - 0.5 * u - 0.5 * v, u, v, scene->AddMaterial(box.top), box.tile_m));
    scene->quads.back().days = box.days;
  }
}

void AddPanel(const PanelSpec& p, Scene* scene) {
  const double yaw = DegreesToRadians(p.yaw_deg);
  scene->quads.push_back(VerticalQuad(p.center, {std::cos(yaw), std::sin(yaw), 0}, p.width,
                                      p.height, scene->AddMaterial(p.material), p.tile_m));
  scene->quads.back().days = p.days;
}

Scene BuildScene(const SceneSpec& s) {
  Scene scene;
  scene.spec = s;
  const int floor = scene.AddMaterial(s.floor), ceiling = scene.AddMaterial(s.ceiling);
  const int wall = scene.AddMaterial(s.wall), lower = scene.AddMaterial(s.lower_floor);
  AddFloor(s, floor, &scene);
  scene.quads.push_back(HorizontalQuad(s.x0, s.y0, s.x1, s.y1, s.height, false, ceiling,
                                       s.ceiling_tile_m));
  const double cx = 0.5 * (s.x0 + s.x1), cy = 0.5 * (s.y0 + s.y1), h = s.height;
  const double w = s.x1 - s.x0, l = s.y1 - s.y0;
  scene.quads.push_back(VerticalQuad({s.x0, cy, h / 2}, {1, 0, 0}, l, h, wall, s.wall_tile_m));
  scene.quads.push_back(VerticalQuad({s.x1, cy, h / 2}, {-1, 0, 0}, l, h, wall, s.wall_tile_m));
  scene.quads.push_back(VerticalQuad({cx, s.y0, h / 2}, {0, 1, 0}, w, h, wall, s.wall_tile_m));
  scene.quads.push_back(VerticalQuad({cx, s.y1, h / 2}, {0, -1, 0}, w, h, wall, s.wall_tile_m));
  for (const auto& hole : s.holes) AddHole(s, hole, wall, lower, &scene);
  for (const auto& box : s.boxes) AddBox(box, &scene);
  for (const auto& panel : s.panels) AddPanel(panel, &scene);
  return scene;
}

// ---- Seeded floor generator --------------------------------------------------

bool FloorOptions::Check(std::string* why) const {
  if (blocks_x < 1 || blocks_y < 1) return *why = "floor needs at least 1x1 blocks", false;
  if (block_x < 2 || block_y < 2) return *why = "blocks must be at least 2 m wide", false;
  if (corridor < 3) return *why = "corridors must be at least 3 m wide", false;
  if (height < 2.5) return *why = "ceiling must be at least 2.5 m high", false;
  return true;
}

namespace {

std::string Key(const std::string& kind, int variant) {
  return kind + ":" + std::to_string(variant);
}

// Panels along one face of a block: shop windows, posters, signage, glossy
// panels and textureless temporary walls.
void DecorateFace(const Eigen::Vector3d& face_center, const Eigen::Vector3d& normal,
                  double face_width, std::mt19937_64& rng, int* poster_counter,
                  std::vector<PanelSpec>* out) {
  std::uniform_real_distribution<double> u01(0, 1);
  const double yaw = std::atan2(normal.y(), normal.x()) * 180 / kPi;
  const Eigen::Vector3d along = Eigen::Vector3d::UnitZ().cross(normal).normalized();
  Eigen::Vector3d base = face_center + 0.02 * normal;  // just off the wall
  base.z() = 0;                                        // heights below are above the floor
  double pos = -0.5 * face_width + 0.4;
  while (pos < 0.5 * face_width - 1.2) {
    const double kind = u01(rng);
    PanelSpec p;
    p.yaw_deg = yaw;
    if (kind < 0.40) {  // poster
      p.width = 1.0 + u01(rng);
      p.height = 1.2 + 0.8 * u01(rng);
      p.material = {Key("poster", (*poster_counter)++)};
      p.center = base + along * (pos + p.width / 2) + Eigen::Vector3d(0, 0, 1.0 + p.height / 2);
    } else if (kind < 0.55) {  // digital signage: content changes between days
      p.width = 1.6;
      p.height = 0.9;
      p.material = {Key("signage", (*poster_counter)++)};
      p.center = base + along * (pos + p.width / 2) + Eigen::Vector3d(0, 0, 2.4);
    } else if (kind < 0.70) {  // glossy, reflective-looking panel
      p.width = 2.0 + u01(rng);
      p.height = 2.2;
      p.material = {Key("glossy", static_cast<int>(rng() % 4)), true};
      p.center = base + along * (pos + p.width / 2) + Eigen::Vector3d(0, 0, 1.1);
    } else if (kind < 0.82) {  // textureless temporary wall
      p.width = 2.5 + 1.5 * u01(rng);
      p.height = 2.6;
      p.material = {Key("plain", static_cast<int>(rng() % 4))};
      p.center = base + 0.03 * normal + along * (pos + p.width / 2) + Eigen::Vector3d(0, 0, 1.3);
    } else {  // shop window with a name board
      p.width = 2.5 + u01(rng);
      p.height = 2.8;
      p.material = {Key("shopfront", (*poster_counter)++)};
      p.center = base + along * (pos + p.width / 2) + Eigen::Vector3d(0, 0, 1.4);
    }
    if (pos + p.width > 0.5 * face_width - 0.2) break;
    out->push_back(p);
    pos += p.width + 0.3 + 1.5 * u01(rng);
  }
}

// One generated floor: a grid of shop blocks between corridors, drawn from
// one random stream in a fixed order (the draws' order is the floor: keep it).
struct FloorMaker {
  FloorMaker(const FloorOptions& o, uint64_t seed)
      : o(o), rng(seed * 0x9E3779B97F4A7C15ull + 17), u01(0, 1),
        pitch_x(o.block_x + o.corridor), pitch_y(o.block_y + o.corridor) {}

  const FloorOptions& o;
  std::mt19937_64 rng;
  std::uniform_real_distribution<double> u01;
  const double pitch_x, pitch_y;
  SceneSpec s;
  int poster_counter = 0;
  std::vector<PanelSpec> twin_panels;  // panels of the first block, relative to its centre

  int Node(int i, int j) const { return j * (o.blocks_x + 1) + i; }

  void Outline() {
    s.x0 = 0;
    s.y0 = 0;
    s.x1 = o.blocks_x * o.block_x + (o.blocks_x + 1) * o.corridor;
    s.y1 = o.blocks_y * o.block_y + (o.blocks_y + 1) * o.corridor;
    s.height = o.height;
    s.floor = {Key("tiles", static_cast<int>(rng() % 3))};
    s.wall = {Key("bricks", static_cast<int>(rng() % 3))};
    s.ceiling = {Key("ceiling", 0)};
    s.lower_floor = {Key("tiles", 3)};
  }

  // Walk graph: corridor intersections; the start at the one nearest the middle.
  void WalkGraph() {
    for (int j = 0; j <= o.blocks_y; ++j)
      for (int i = 0; i <= o.blocks_x; ++i)
        s.walk.nodes.emplace_back(o.corridor / 2 + i * pitch_x, o.corridor / 2 + j * pitch_y);
    for (int j = 0; j <= o.blocks_y; ++j)
      for (int i = 0; i <= o.blocks_x; ++i) {
        if (i < o.blocks_x) s.walk.edges.emplace_back(Node(i, j), Node(i + 1, j));
        if (j < o.blocks_y) s.walk.edges.emplace_back(Node(i, j), Node(i, j + 1));
      }
    s.start_node = s.walk.Nearest({0.5 * (s.x0 + s.x1), 0.5 * (s.y0 + s.y1)});
    s.query_split_x = s.walk.nodes[s.start_node].x() + 0.5 * o.corridor;
  }

  // A floor opening in place of the block at c, with a railing around it.
  void Opening(const Eigen::Vector3d& c) {
    HoleSpec h{c.x() - o.block_x / 2 + 0.5, c.y() - o.block_y / 2 + 0.5,
               c.x() + o.block_x / 2 - 0.5, c.y() + o.block_y / 2 - 0.5};
    s.holes.push_back(h);
    const double rw = h.x1 - h.x0, rl = h.y1 - h.y0;
    const Material rail{"glossy:0", true};
    s.boxes.push_back({{c.x(), h.y0 - 0.05, 0.55}, {rw + 0.1, 0.1, 1.1}, 0, {rail}, rail, 1});
    s.boxes.push_back({{c.x(), h.y1 + 0.05, 0.55}, {rw + 0.1, 0.1, 1.1}, 0, {rail}, rail, 1});
    s.boxes.push_back({{h.x0 - 0.05, c.y(), 0.55}, {0.1, rl, 1.1}, 0, {rail}, rail, 1});
    s.boxes.push_back({{h.x1 + 0.05, c.y(), 0.55}, {0.1, rl, 1.1}, 0, {rail}, rail, 1});
  }

  // Kiosks against the block at c, moved between days (present on about half of its faces).
  void Kiosks(const Eigen::Vector3d& c, const Eigen::Vector3d (&faces)[4]) {
    for (const auto& n : faces) {
      if (u01(rng) > 0.5) continue;
      const bool along_y = std::abs(n.x()) > 0;
      const double half = along_y ? o.block_x / 2 : o.block_y / 2;
      const double room = (along_y ? o.block_y : o.block_x) / 2 - 1.2;
      const Eigen::Vector3d t = Eigen::Vector3d::UnitZ().cross(n);
      BoxSpec kiosk;
      kiosk.center = c + n * (half + 0.28) + t * (room * (2 * u01(rng) - 1));
      kiosk.center.z() = 0.9;
      kiosk.size = along_y ? Eigen::Vector3d(0.5, 1.4, 1.8) : Eigen::Vector3d(1.4, 0.5, 1.8);
      kiosk.sides = {{Key("poster", poster_counter++)}};
      kiosk.top = {"plain:2"};
      kiosk.tile_m = 0;
      kiosk.days = static_cast<uint32_t>(rng()) | 1u;  // always there on day 0
      s.boxes.push_back(kiosk);
    }
  }

  // Shop block (i, j) at c: its box, its faces' panels and kiosks; the twin
  // (last of the bottom row) repeats the first block's box and panels.
  void Block(int i, int j, const Eigen::Vector3d& c) {
    const bool twin = (j == 0 && i == o.blocks_x - 1 && o.blocks_x >= 2);
    BoxSpec b;
    b.center = c;
    b.size = {o.block_x, o.block_y, o.height};
    b.sides = {{Key("noise", (i + 2 * j) % 5)}};
    if (twin) b.sides = s.boxes.empty() ? b.sides : s.boxes.front().sides;
    b.tile_m = 3.0;
    s.boxes.push_back(b);
    if (twin) {
      for (auto p : twin_panels) {
        p.center += c;
        s.panels.push_back(p);
      }
      return;
    }
    std::vector<PanelSpec> panels;
    const Eigen::Vector3d faces[4] = {{1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}};
    for (const auto& n : faces) {
      const double half = std::abs(n.x()) > 0 ? o.block_x / 2 : o.block_y / 2;
      const double width = std::abs(n.x()) > 0 ? o.block_y : o.block_x;
      DecorateFace(c + n * half, n, width, rng, &poster_counter, &panels);
    }
    for (const auto& p : panels) s.panels.push_back(p);
    Kiosks(c, faces);
    if (i == 0 && j == 0)
      for (auto p : panels) {
        p.center -= c;
        twin_panels.push_back(p);
      }
  }

  // Shop blocks; the first and last of the bottom row are identical (repetition),
  // the middle one of the top row is a floor opening when there are >= 3 blocks.
  void Blocks() {
    const int hole_i = o.blocks_x >= 3 ? o.blocks_x / 2 : -1, hole_j = o.blocks_y - 1;
    for (int j = 0; j < o.blocks_y; ++j)
      for (int i = 0; i < o.blocks_x; ++i) {
        const Eigen::Vector3d c(o.corridor + i * pitch_x + o.block_x / 2,
                                o.corridor + j * pitch_y + o.block_y / 2, o.height / 2);
        if (i == hole_i && j == hole_j && (o.blocks_y > 1 || o.blocks_x >= 3))
          Opening(c);
        else
          Block(i, j, c);
      }
  }

  // Perimeter wall decoration, pillars beside corridor intersections (off
  // the walking lanes), a row of turnstiles across the first corridor segment
  // of the bottom row.
  void Fittings() {
    const double cx = 0.5 * (s.x0 + s.x1), cy = 0.5 * (s.y0 + s.y1);
    DecorateFace({s.x0, cy, 0}, {1, 0, 0}, s.y1 - s.y0, rng, &poster_counter, &s.panels);
    DecorateFace({s.x1, cy, 0}, {-1, 0, 0}, s.y1 - s.y0, rng, &poster_counter, &s.panels);
    DecorateFace({cx, s.y0, 0}, {0, 1, 0}, s.x1 - s.x0, rng, &poster_counter, &s.panels);
    DecorateFace({cx, s.y1, 0}, {0, -1, 0}, s.x1 - s.x0, rng, &poster_counter, &s.panels);
    for (size_t n = 0; n < s.walk.nodes.size(); n += 2) {
      const Eigen::Vector2d p = s.walk.nodes[n] + Eigen::Vector2d(1, 1) * (o.corridor / 2 - 0.45);
      if (p.x() > s.x1 - 0.5 || p.y() > s.y1 - 0.5) continue;
      s.boxes.push_back({{p.x(), p.y(), o.height / 2}, {0.5, 0.5, o.height}, 0,
                         {{Key("noise", 5 + static_cast<int>(n % 3))}}, {}, 1.0});
    }
    if (o.blocks_x >= 1) {
      const Eigen::Vector2d a = s.walk.nodes[Node(0, 0)], b = s.walk.nodes[Node(1, 0)];
      const double x = 0.5 * (a.x() + b.x());
      for (double dy : {-1.8, -0.6, 0.6, 1.8})
        s.boxes.push_back({{x, a.y() + dy, 0.5}, {0.9, 0.2, 1.0}, 0, {{"glossy:1", true}},
                           {"plain:1"}, 1.0});
    }
  }
};

}  // namespace

SceneSpec GenerateFloor(const FloorOptions& o, uint64_t seed) {
  std::string why;
  if (!o.Check(&why)) throw ParamError(why);
  FloorMaker m(o, seed);
  m.Outline();
  m.WalkGraph();
  m.Blocks();
  m.Fittings();
  return std::move(m.s);
}

// ---- YAML floor plans --------------------------------------------------------

namespace {

struct YamlReader {
  std::string file;

  [[noreturn]] void Fail(const YAML::Node& n, const std::string& field, const std::string& what) const {
    const int64_t line = n.IsDefined() ? n.Mark().line + 1 : 0;
    throw InputError(file, line, field, what);
  }
  double Number(const YAML::Node& n, const std::string& field) const {
    try {
      return n.as<double>();
    } catch (const YAML::Exception&) {
      Fail(n, field, "expected a number");
    }
  }
  Eigen::Vector3d Vec(const YAML::Node& n, const std::string& field, int size) const {
    if (!n.IsSequence() || static_cast<int>(n.size()) != size)
      Fail(n, field, "expected a list of " + std::to_string(size) + " numbers");
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    for (int i = 0; i < size; ++i) v[i] = Number(n[i], field);
    return v;
  }
  Material Mat(const YAML::Node& n, const std::string& field) const {
    if (n.IsScalar()) return {n.as<std::string>()};
    if (n.IsMap() && n["texture"])
      return {n["texture"].as<std::string>(), n["glossy"] && n["glossy"].as<bool>()};
    Fail(n, field, "expected a texture key or {texture: ..., glossy: ...}");
  }
  // `days: [0, 2]` -> bit mask; absent -> 0 (every day).
  uint32_t Days(const YAML::Node& map, const std::string& where) const {
    const YAML::Node n = map["days"];
    if (!n) return 0;
    if (!n.IsSequence() || n.size() == 0) Fail(n, where + ".days", "expected a non-empty list of days");
    uint32_t mask = 0;
    for (const auto& d : n) {
      const double day = Number(d, where + ".days");
      if (day < 0 || day != std::floor(day)) Fail(d, where + ".days", "days are integers >= 0");
      mask |= 1u << (static_cast<int>(day) % 32);
    }
    return mask;
  }
  double Get(const YAML::Node& map, const char* key, double fallback, const std::string& where) const {
    return map[key] ? Number(map[key], where + "." + key) : fallback;
  }
};

YAML::Node LoadYaml(const YamlReader& r) {
  try {
    return YAML::LoadFile(r.file);
  } catch (const YAML::ParserException& e) {
    throw InputError(r.file, e.mark.line + 1, "", e.msg);
  } catch (const YAML::Exception& e) {
    throw InputError(r.file, 0, "", std::string("cannot read: ") + e.what());
  }
}

// extent, height and the surfaces' materials.
void ReadOutline(const YamlReader& r, const YAML::Node& root, SceneSpec* s) {
  if (!root["extent"]) r.Fail(root, "extent", "missing [x0, y0, x1, y1]");
  const YAML::Node ext = root["extent"];
  if (!ext.IsSequence() || ext.size() != 4) r.Fail(ext, "extent", "expected [x0, y0, x1, y1]");
  s->x0 = r.Number(ext[0], "extent");
  s->y0 = r.Number(ext[1], "extent");
  s->x1 = r.Number(ext[2], "extent");
  s->y1 = r.Number(ext[3], "extent");
  if (s->x1 <= s->x0 || s->y1 <= s->y0) r.Fail(ext, "extent", "empty floor");
  s->height = r.Get(root, "height", s->height, "");
  if (s->height <= 0) r.Fail(root["height"], "height", "must be positive");
  for (const char* k : {"floor", "ceiling", "wall", "lower_floor"}) {
    if (!root[k]) continue;
    Material m = r.Mat(root[k], k);
    (std::string(k) == "floor" ? s->floor
     : std::string(k) == "ceiling" ? s->ceiling
     : std::string(k) == "wall"    ? s->wall
                                   : s->lower_floor) = m;
  }
}

// root[key]: absent, or a list.
YAML::Node ListOf(const YamlReader& r, const YAML::Node& root, const char* key) {
  const YAML::Node n = root[key];
  if (n && !n.IsSequence()) r.Fail(n, key, "expected a list");
  return n;
}

BoxSpec ReadBox(const YamlReader& r, const YAML::Node& b, const std::string& where) {
  BoxSpec box;
  if (!b["center"] || !b["size"]) r.Fail(b, where, "needs center and size");
  box.center = r.Vec(b["center"], where + ".center", 3);
  box.size = r.Vec(b["size"], where + ".size", 3);
  if ((box.size.array() <= 0).any()) r.Fail(b["size"], where + ".size", "must be positive");
  box.yaw_deg = r.Get(b, "yaw_deg", 0, where);
  box.tile_m = r.Get(b, "tile_m", box.tile_m, where);
  if (b["sides"]) {
    if (b["sides"].IsSequence())
      for (const auto& m : b["sides"]) box.sides.push_back(r.Mat(m, where + ".sides"));
    else
      box.sides.push_back(r.Mat(b["sides"], where + ".sides"));
  }
  if (b["top"]) box.top = r.Mat(b["top"], where + ".top");
  box.days = r.Days(b, where);
  return box;
}

PanelSpec ReadPanel(const YamlReader& r, const YAML::Node& p, const std::string& where) {
  PanelSpec panel;
  if (!p["center"] || !p["material"]) r.Fail(p, where, "needs center and material");
  panel.center = r.Vec(p["center"], where + ".center", 3);
  panel.yaw_deg = r.Get(p, "yaw_deg", 0, where);
  panel.width = r.Get(p, "width", 1, where);
  panel.height = r.Get(p, "height", 1, where);
  panel.tile_m = r.Get(p, "tile_m", 0, where);
  panel.material = r.Mat(p["material"], where + ".material");
  panel.days = r.Days(p, where);
  return panel;
}

HoleSpec ReadHole(const YamlReader& r, const YAML::Node& n, const std::string& where) {
  if (!n.IsSequence() || n.size() != 4) r.Fail(n, where, "expected [x0, y0, x1, y1]");
  HoleSpec h{r.Number(n[0], where), r.Number(n[1], where), r.Number(n[2], where), r.Number(n[3], where)};
  if (h.x1 <= h.x0 || h.y1 <= h.y0) r.Fail(n, where, "empty hole");
  return h;
}

// The walk graph, its start node and the query split.
void ReadWalk(const YamlReader& r, const YAML::Node& root, SceneSpec* s) {
  const YAML::Node walk = root["walk"];
  if (!walk || !walk["nodes"] || !walk["edges"])
    r.Fail(walk ? walk : root, "walk", "missing walk: {nodes: [[x, y], ...], edges: [[i, j], ...]}");
  for (size_t i = 0; i < walk["nodes"].size(); ++i) {
    const Eigen::Vector3d v = r.Vec(walk["nodes"][i], "walk.nodes[" + std::to_string(i) + "]", 2);
    s->walk.nodes.emplace_back(v.x(), v.y());
  }
  for (size_t i = 0; i < walk["edges"].size(); ++i) {
    const std::string where = "walk.edges[" + std::to_string(i) + "]";
    const Eigen::Vector3d e = r.Vec(walk["edges"][i], where, 2);
    const int a = static_cast<int>(e.x()), b = static_cast<int>(e.y());
    const int n = static_cast<int>(s->walk.nodes.size());
    if (a < 0 || b < 0 || a >= n || b >= n || a == b) r.Fail(walk["edges"][i], where, "node index out of range");
    s->walk.edges.emplace_back(a, b);
  }
  if (s->walk.nodes.size() < 2 || s->walk.edges.empty()) r.Fail(walk, "walk", "needs >= 2 nodes and an edge");
  s->start_node = static_cast<int>(r.Get(root, "start_node", 0, ""));
  if (s->start_node < 0 || s->start_node >= static_cast<int>(s->walk.nodes.size()))
    r.Fail(root["start_node"], "start_node", "node index out of range");
  s->query_split_x = r.Get(root, "query_split_x", s->walk.nodes[s->start_node].x(), "");
}

}  // namespace

SceneSpec LoadSceneSpec(const std::filesystem::path& yaml_file) {
  YamlReader r{yaml_file.string()};
  const YAML::Node root = LoadYaml(r);
  if (!root.IsMap()) throw InputError(r.file, 1, "", "a floor plan is a YAML map");
  SceneSpec s;
  ReadOutline(r, root, &s);
  if (const auto boxes = ListOf(r, root, "boxes"))
    for (size_t i = 0; i < boxes.size(); ++i) s.boxes.push_back(ReadBox(r, boxes[i], "boxes[" + std::to_string(i) + "]"));
  if (const auto panels = ListOf(r, root, "panels"))
    for (size_t i = 0; i < panels.size(); ++i)
      s.panels.push_back(ReadPanel(r, panels[i], "panels[" + std::to_string(i) + "]"));
  if (const auto holes = ListOf(r, root, "holes"))
    for (size_t i = 0; i < holes.size(); ++i) s.holes.push_back(ReadHole(r, holes[i], "holes[" + std::to_string(i) + "]"));
  ReadWalk(r, root, &s);
  return s;
}

}  // namespace locforge::sim

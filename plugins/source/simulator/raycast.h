// Ray casting: a bounding-volume hierarchy over the scene quads, and the World
// (static scene of one day + the people at one instant) that rays hit.
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_RAYCAST_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_RAYCAST_H_

#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <vector>

#include "people.h"
#include "people_grid.h"
#include "sah_bvh.h"
#include "scene.h"
#include "texture.h"

namespace locforge::sim {

struct Hit {
  double t = std::numeric_limits<double>::infinity();  // distance along the unit ray
  int quad = -1;        // index in Scene::quads, or -1
  int person = -1;      // index in the crowd, or -1
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit, facing the ray
  Eigen::Vector2d tex_uv = Eigen::Vector2d::Zero();   // texture coordinates (periods)
  double period_m = 1;  // metres per texture period (for mip selection)
  bool hit() const { return quad >= 0 || person >= 0; }
};

// Where the ray o + t d crosses the plane of quad q (false when parallel).
// Every ray-quad test goes through these two functions, so all compute the
// same numbers for the same quad and ray.
inline bool CrossQuadPlane(const Quad& q, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                           double* denom, double* t) {
  *denom = q.normal.dot(d);
  if (std::abs(*denom) < 1e-12) return false;
  *t = q.normal.dot(q.origin - o) / *denom;
  return true;
}
// Whether the crossing at t lies on the quad: (a, b) in edge units, uu and vv
// the squared edge lengths.
inline bool InsideQuad(const Quad& q, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t,
                       double* a, double* b, double* uu, double* vv) {
  const Eigen::Vector3d rel = o + t * d - q.origin;
  *uu = q.u_edge.squaredNorm();
  *vv = q.v_edge.squaredNorm();
  *a = rel.dot(q.u_edge) / *uu;
  *b = rel.dot(q.v_edge) / *vv;
  return !(*a < 0 || *a > 1 || *b < 0 || *b > 1);
}

// The search for the nearest quad shared by the fast paths (SahBvh, the
// renderer's screen tiles): keeps the nearest quad hit in (t_min, t], tested
// as IntersectQuad does, and notices a second quad hit at exactly that
// distance. Then the order of the tests decides (the first one wins), and
// only QuadBvh's order defines the simulator's output: callers fall back to it.
struct NearestQuadSearch {
  double t = std::numeric_limits<double>::infinity();
  int quad = -1;
  double tie_t = -std::numeric_limits<double>::infinity();

  void Test(const Quad& q, int index, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min) {
    double denom, t_hit, a, b, uu, vv;
    if (!CrossQuadPlane(q, o, d, &denom, &t_hit)) return;
    if (t_hit <= t_min || t_hit > t) return;
    if (!InsideQuad(q, o, d, t_hit, &a, &b, &uu, &vv)) return;
    if (t_hit < t) {
      t = t_hit;
      quad = index;
    } else if (index != quad) {
      tie_t = t_hit;
    }
  }
  bool tie() const { return quad >= 0 && tie_t == t; }
};

// Ray-quad and ray-cylinder tests; t must lie in (t_min, hit->t).
bool IntersectQuad(const Quad& q, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                   Hit* hit);
bool IntersectCylinder(const Cylinder& c, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                       double t_min, Hit* hit);

class QuadBvh {
 public:
  explicit QuadBvh(const std::vector<Quad>& quads);
  // Keeps a reference to `quads`, which must outlive the BVH.
  // Nearest quad along o + t d with t in (t_min, hit->t); updates `hit`.
  bool Intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min, Hit* hit) const;
  size_t num_nodes() const { return nodes_.size(); }

 private:
  struct Node {
    Eigen::Vector3d lo, hi;
    int left = -1, right = -1;  // children, or -1 for a leaf
    int first = 0, count = 0;   // leaf range in order_
  };
  int Build(int first, int count, const std::vector<Eigen::Vector3d>& centroids);

  const std::vector<Quad>& quads_;
  std::vector<int> order_;
  std::vector<Node> nodes_;
};

// The scene on one day plus people; what cameras and LiDARs observe.
class World {
 public:
  World(const Scene& scene, const Crowd& crowd, TextureLibrary* textures, int day);

  const Scene& scene() const { return scene_; }
  // The scene's quads present on this world's day (Hit::quad indexes these).
  const std::vector<Quad>& quads() const { return quads_; }
  const Crowd& crowd() const { return crowd_; }

  // Nearest surface along the unit ray o + t d, t > t_min, among the quads
  // (QuadBvh: its test order decides exact ties) and the given people
  // cylinders (Crowd::At(time)) in their order. The reference that the fast
  // paths below equal bit for bit.
  bool Cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const std::vector<Cylinder>& people,
            Hit* hit, double t_min = 1e-6) const;

  // The same hit as Cast with every person, bit for bit, faster: the quads
  // through SahBvh (NearestQuad), then NearPeople.
  template <typename CylindersOf>
  bool CastNear(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const PeopleGrid& grid,
                const CylindersOf& cylinders_of, std::vector<int>* scratch, Hit* hit,
                double t_min = 1e-6) const {
    NearestQuad(o, d, t_min, hit);
    NearPeople(o, d, grid, cylinders_of, scratch, hit, t_min);
    return hit->hit();
  }

  // The quad that Cast reports, into a fresh `hit`, found with SahBvh.
  void NearestQuad(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min, Hit* hit) const;
  // The end of a nearest-quad search over all quads that may be hit: its
  // winner into a fresh `hit`, or QuadBvh's answer when the search saw a tie
  // or was not `complete` (rays it cannot handle).
  void ReportQuad(const NearestQuadSearch& search, bool complete, const Eigen::Vector3d& o,
                  const Eigen::Vector3d& d, double t_min, Hit* hit) const;

  // The people part of Cast, testing only the items `grid` puts near the ray
  // before hit->t: item k stands for the cylinders [first, last) =
  // cylinders_of(k), consecutive in Cast's order. `scratch` holds the
  // candidates (one per thread).
  template <typename CylindersOf>
  void NearPeople(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const PeopleGrid& grid,
                  const CylindersOf& cylinders_of, std::vector<int>* scratch, Hit* hit,
                  double t_min = 1e-6) const {
    grid.Candidates(o, d, t_min, hit->t, scratch);
    for (int k : *scratch) {
      const auto [first, last] = cylinders_of(k);
      for (const Cylinder* c = first; c != last; ++c) IntersectCylinder(*c, o, d, t_min, hit);
    }
  }

  // Surface colour (RGB, 0-255) at a hit; `footprint_m` is the size of the
  // pixel on the surface, used to pick the mip level.
  Eigen::Vector3f Albedo(const Hit& hit, double footprint_m) const;
  bool Glossy(const Hit& hit) const;

 private:
  const Scene& scene_;
  const Crowd& crowd_;
  std::vector<Quad> quads_;
  QuadBvh bvh_;  // its test order decides ties: the reference
  SahBvh sah_;
  std::vector<const Texture*> material_textures_;
  std::vector<const Texture*> person_textures_;
};

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_RAYCAST_H_

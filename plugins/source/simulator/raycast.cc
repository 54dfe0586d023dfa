#include "raycast.h"

#include <algorithm>
#include <cmath>

namespace locforge::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::vector<Quad> QuadsOfDay(const Scene& scene, int day) {
  std::vector<Quad> out;
  for (const Quad& q : scene.quads)
    if (q.PresentOn(day)) out.push_back(q);
  return out;
}

}  // namespace

bool IntersectQuad(const Quad& q, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                   Hit* hit) {
  double denom, t, a, b, uu, vv;
  if (!CrossQuadPlane(q, o, d, &denom, &t)) return false;
  if (t <= t_min || t >= hit->t) return false;
  if (!InsideQuad(q, o, d, t, &a, &b, &uu, &vv)) return false;
  hit->t = t;
  hit->quad = -1;  // set by the caller, which knows the index
  hit->person = -1;
  hit->point = o + t * d;
  hit->normal = denom < 0 ? q.normal : Eigen::Vector3d(-q.normal);
  const double w = std::sqrt(uu), h = std::sqrt(vv);
  if (q.tile_m > 0) {
    hit->tex_uv = {(a * w + q.tex_offset.x()) / q.tile_m, -(b * h + q.tex_offset.y()) / q.tile_m};
    hit->period_m = q.tile_m;
  } else {
    hit->tex_uv = {a, 1 - b};
    hit->period_m = std::sqrt(w * h);
  }
  return true;
}

bool IntersectCylinder(const Cylinder& c, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                       double t_min, Hit* hit) {
  const Eigen::Vector2d oc = o.head<2>() - c.center, dxy = d.head<2>();
  const double a = dxy.squaredNorm();
  double t = std::numeric_limits<double>::infinity();
  Eigen::Vector3d normal;
  if (a > 1e-12) {  // side wall, entering root only
    const double b = oc.dot(dxy), cc = oc.squaredNorm() - c.radius * c.radius;
    const double disc = b * b - a * cc;
    if (disc >= 0) {
      const double ts = (-b - std::sqrt(disc)) / a;
      const double z = o.z() + ts * d.z();
      if (ts > t_min && z >= c.z0 && z <= c.z1) {
        t = ts;
        const Eigen::Vector2d n = (oc + ts * dxy) / c.radius;
        normal = {n.x(), n.y(), 0};
      }
    }
  }
  if (std::abs(d.z()) > 1e-12) {  // top cap, seen from above
    const double tc = (c.z1 - o.z()) / d.z();
    if (d.z() < 0 && tc > t_min && tc < t && (oc + tc * dxy).squaredNorm() <= c.radius * c.radius) {
      t = tc;
      normal = Eigen::Vector3d::UnitZ();
    }
  }
  if (!(t < hit->t)) return false;
  hit->t = t;
  hit->quad = -1;
  hit->person = c.person;
  hit->point = o + t * d;
  hit->normal = normal;
  const Eigen::Vector2d rel = hit->point.head<2>() - c.center;
  const double frac = (hit->point.z() - c.z0) / (c.z1 - c.z0);
  hit->tex_uv = {std::atan2(rel.y(), rel.x()) / (2 * kPi), c.v0 + (c.v1 - c.v0) * (1 - frac)};
  hit->period_m = 2 * kPi * c.radius;
  return true;
}

QuadBvh::QuadBvh(const std::vector<Quad>& quads) : quads_(quads) {
  std::vector<Eigen::Vector3d> centroids;
  for (const auto& q : quads) centroids.push_back(q.origin + 0.5 * (q.u_edge + q.v_edge));
  order_.resize(quads.size());
  for (size_t i = 0; i < order_.size(); ++i) order_[i] = static_cast<int>(i);
  nodes_.reserve(2 * quads.size() + 1);
  if (!quads.empty()) Build(0, static_cast<int>(quads.size()), centroids);
}

int QuadBvh::Build(int first, int count, const std::vector<Eigen::Vector3d>& centroids) {
  Node node;
  node.lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  node.hi = -node.lo;
  Eigen::Vector3d clo = node.lo, chi = node.hi;
  for (int i = first; i < first + count; ++i) {
    const Quad& q = quads_[order_[i]];
    for (const Eigen::Vector3d& p : {q.origin, Eigen::Vector3d(q.origin + q.u_edge),
                                     Eigen::Vector3d(q.origin + q.v_edge),
                                     Eigen::Vector3d(q.origin + q.u_edge + q.v_edge)}) {
      node.lo = node.lo.cwiseMin(p);
      node.hi = node.hi.cwiseMax(p);
    }
    clo = clo.cwiseMin(centroids[order_[i]]);
    chi = chi.cwiseMax(centroids[order_[i]]);
  }
  // Flat quads give zero-thickness boxes; pad so the slab test stays robust.
  node.lo.array() -= 1e-6;
  node.hi.array() += 1e-6;
  const int index = static_cast<int>(nodes_.size());
  nodes_.push_back(node);
  if (count <= 4) {
    nodes_[index].first = first;
    nodes_[index].count = count;
    return index;
  }
  int axis;
  (chi - clo).maxCoeff(&axis);
  const int mid = first + count / 2;
  std::nth_element(order_.begin() + first, order_.begin() + mid, order_.begin() + first + count,
                   [&](int a, int b) { return centroids[a][axis] < centroids[b][axis]; });
  const int left = Build(first, mid - first, centroids);
  const int right = Build(mid, first + count - mid, centroids);
  nodes_[index].left = left;
  nodes_[index].right = right;
  return index;
}

bool QuadBvh::Intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                        Hit* hit) const {
  if (nodes_.empty()) return false;
  const Eigen::Vector3d inv_d = d.cwiseInverse();
  int stack[64];
  int top = 0;
  stack[top++] = 0;
  bool found = false;
  while (top > 0) {
    const Node& n = nodes_[stack[--top]];
    if (!(BoxEntry(n.lo, n.hi, o, inv_d, hit->t) < hit->t)) continue;
    if (n.left < 0) {
      for (int i = n.first; i < n.first + n.count; ++i)
        if (IntersectQuad(quads_[order_[i]], o, d, t_min, hit)) {
          hit->quad = order_[i];
          found = true;
        }
      continue;
    }
    // Visit the nearer child first (pushed last).
    const double tl = BoxEntry(nodes_[n.left].lo, nodes_[n.left].hi, o, inv_d, hit->t);
    const double tr = BoxEntry(nodes_[n.right].lo, nodes_[n.right].hi, o, inv_d, hit->t);
    if (tl < tr) {
      if (tr < hit->t) stack[top++] = n.right;
      if (tl < hit->t) stack[top++] = n.left;
    } else {
      if (tl < hit->t) stack[top++] = n.left;
      if (tr < hit->t) stack[top++] = n.right;
    }
  }
  return found;
}

World::World(const Scene& scene, const Crowd& crowd, TextureLibrary* textures, int day)
    : scene_(scene), crowd_(crowd), quads_(QuadsOfDay(scene, day)), bvh_(quads_), sah_(quads_) {
  for (const auto& m : scene.materials) material_textures_.push_back(textures->Get(m.texture, day));
  for (const auto& p : crowd.people()) person_textures_.push_back(textures->Get(p.texture, day));
}

bool World::Cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                 const std::vector<Cylinder>& people, Hit* hit, double t_min) const {
  bvh_.Intersect(o, d, t_min, hit);
  for (const auto& c : people) IntersectCylinder(c, o, d, t_min, hit);
  return hit->hit();
}

void World::NearestQuad(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min, Hit* hit) const {
  // A ray with a zero direction component can meet a box face edge-on, where
  // the slab test's 0 x inf is a NaN: such rays take QuadBvh's path too.
  const bool regular = std::abs(d.x()) > 1e-300 && std::abs(d.y()) > 1e-300 && std::abs(d.z()) > 1e-300;
  ReportQuad(regular ? sah_.Intersect(o, d, t_min, hit->t) : NearestQuadSearch(), regular, o, d, t_min, hit);
}

void World::ReportQuad(const NearestQuadSearch& search, bool complete, const Eigen::Vector3d& o,
                       const Eigen::Vector3d& d, double t_min, Hit* hit) const {
  if (complete && !search.tie()) {
    if (search.quad < 0) return;
    if (IntersectQuad(quads_[search.quad], o, d, t_min, hit)) {
      hit->quad = search.quad;
      return;
    }
  }
  bvh_.Intersect(o, d, t_min, hit);
}

Eigen::Vector3f World::Albedo(const Hit& hit, double footprint_m) const {
  const Texture* tex = hit.person >= 0 ? person_textures_[hit.person]
                                       : material_textures_[quads_[hit.quad].material];
  const double texels = footprint_m / hit.period_m * tex->levels[0].size;
  return tex->Sample(hit.tex_uv.x(), hit.tex_uv.y(), texels);
}

bool World::Glossy(const Hit& hit) const {
  return hit.quad >= 0 && scene_.materials[quads_[hit.quad].material].glossy;
}

}  // namespace locforge::sim

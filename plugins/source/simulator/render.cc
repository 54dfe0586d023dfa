#include "render.h"

#include "screen_tiles.h"

#include <algorithm>
#include <cmath>

namespace locforge::sim {
namespace {

uint64_t SplitMix(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Zero-mean, unit-variance noise from a hash (sum of 4 uniforms): cheap,
// deterministic per pixel whatever the thread split.
float PixelNoise(uint64_t seed, uint64_t index) {
  uint64_t h = SplitMix(seed ^ SplitMix(index));
  float sum = 0;
  for (int i = 0; i < 4; ++i, h >>= 16) sum += static_cast<float>(h & 0xFFFF) / 65535.f;
  return (sum - 2.f) * 1.7320508f;
}

constexpr double kMinDistance = 1e-6;  // World::Cast's t_min
const Eigen::Vector3d kKeyLight = Eigen::Vector3d(0.3, 0.5, 0.81).normalized();

// The people whose bounding sphere intersects the camera's view cone: most of
// the crowd is behind or beside the camera, and skipping it halves the cost.
std::vector<Cylinder> VisiblePeople(const std::vector<Cylinder>& people, const PinholeCamera& camera,
                                    const Pose& T_world_camera) {
  double half_angle = 0;
  for (double x : {0.0, double(camera.width)})
    for (double y : {0.0, double(camera.height)})
      half_angle = std::max(half_angle, std::acos(camera.Ray(x, y).normalized().z()));
  const Eigen::Vector3d forward = T_world_camera.q * Eigen::Vector3d::UnitZ();
  std::vector<Cylinder> out;
  for (const Cylinder& c : people) {
    const Eigen::Vector3d center(c.center.x(), c.center.y(), 0.5 * (c.z0 + c.z1));
    const double radius = std::hypot(c.radius, 0.5 * (c.z1 - c.z0));
    const Eigen::Vector3d v = center - T_world_camera.t;
    const double dist = v.norm();
    if (dist <= radius || std::acos(std::clamp(v.dot(forward) / dist, -1.0, 1.0)) <=
                              half_angle + std::asin(std::min(1.0, radius / dist)))
      out.push_back(c);
  }
  return out;
}

// The output sized w x h (cleared when it was not).
void SizeOutput(int w, int h, RenderedImage* out) {
  if (out->width != w || out->height != h || out->rgb.size() != size_t(w) * h * 3) {
    out->width = w;
    out->height = h;
    out->rgb.assign(size_t(w) * h * 3, 0);
    out->person_mask.assign(size_t(w) * h, 0);
    out->depth.assign(size_t(w) * h, 0.f);
  }
}

// The fast path: the quads and people each tile of pixels may see.
void FillTiles(const std::vector<Quad>& quads, const std::vector<Cylinder>& visible, ScreenTiles* quad_tiles,
               ScreenTiles* people_tiles) {
  for (int i = 0; i < static_cast<int>(quads.size()); ++i) {
    const Quad& q = quads[i];
    const Eigen::Vector3d corners[4] = {q.origin, q.origin + q.u_edge, q.origin + q.v_edge,
                                        q.origin + q.u_edge + q.v_edge};
    quad_tiles->Add(i, corners, 4);
  }
  for (int k = 0; k < static_cast<int>(visible.size()); ++k) {
    const Cylinder& c = visible[k];
    Eigen::Vector3d corners[8];
    for (int j = 0; j < 8; ++j)
      corners[j] = {c.center.x() + (j & 1 ? c.radius : -c.radius), c.center.y() + (j & 2 ? c.radius : -c.radius),
                    j & 4 ? c.z1 : c.z0};
    people_tiles->Add(k, corners, 8);
  }
}

// The colour of a hit seen along d: the albedo at the pixel's footprint,
// shaded by the key light, with the ceiling lights' mirror-like highlight on
// glossy surfaces (view dependent).
Eigen::Vector3f Shade(const World& world, const Hit& hit, const Eigen::Vector3d& d, double pixel_angle,
                      bool shading) {
  const double cos_view = std::max(0.25, std::abs(hit.normal.dot(d)));
  Eigen::Vector3f color = world.Albedo(hit, hit.t * pixel_angle / cos_view);
  if (shading) {
    color *= static_cast<float>(0.55 + 0.45 * std::abs(hit.normal.dot(kKeyLight)));
    if (world.Glossy(hit)) {
      const Eigen::Vector3d r = d - 2 * d.dot(hit.normal) * hit.normal;
      const double spec = std::pow(std::max(0.0, r.z()), 12.0) + 0.25 * std::pow(std::max(0.0, r.dot(kKeyLight)), 40.0);
      color = 0.6f * color + Eigen::Vector3f::Constant(static_cast<float>(200 * spec));
    }
  }
  return color;
}

// Pixel i: the colour exposed, with noise, as bytes; the person mask; the
// depth (ray length -> z).
void WritePixel(size_t i, const Eigen::Vector3f& color, const Hit& hit, double depth_along_ray, const RenderOptions& o,
                RenderedImage* out) {
  const float scale = static_cast<float>(o.exposure * o.gain);
  for (int c = 0; c < 3; ++c) {
    float v = color[c] * scale;
    if (o.noise_sigma > 0) v += static_cast<float>(o.noise_sigma * o.gain) * PixelNoise(o.noise_seed, i * 3 + c);
    out->rgb[i * 3 + c] = static_cast<uint8_t>(std::clamp(v + 0.5f, 0.f, 255.f));
  }
  out->person_mask[i] = hit.person >= 0 ? 255 : 0;
  out->depth[i] = hit.hit() ? static_cast<float>(depth_along_ray) : 0.f;
}

}  // namespace

double RenderedImage::PersonFraction() const {
  if (person_mask.empty()) return 0;
  size_t n = 0;
  for (uint8_t m : person_mask) n += m != 0;
  return static_cast<double>(n) / person_mask.size();
}

void Render(const World& world, const std::vector<Cylinder>& people, const PinholeCamera& camera,
            const Pose& T_world_camera, const RenderOptions& o, RenderedImage* out, int row_begin,
            int row_end) {
  const int w = camera.width, h = camera.height;
  SizeOutput(w, h, out);
  if (row_end < 0 || row_end > h) row_end = h;
  const std::vector<Cylinder> visible = VisiblePeople(people, camera, T_world_camera);
  const Eigen::Matrix3d R = T_world_camera.R();
  const Eigen::Vector3d origin = T_world_camera.t;
  ScreenTiles quad_tiles(camera, T_world_camera, row_begin, row_end);
  ScreenTiles people_tiles(camera, T_world_camera, row_begin, row_end);
  const std::vector<Quad>& quads = world.quads();
  if (!o.reference_raycast) FillTiles(quads, visible, &quad_tiles, &people_tiles);
  quad_tiles.Finish(true);     // nearest first: a pixel stops at the first quad beyond its hit
  people_tiles.Finish(false);  // in Cast's order
  const auto cast = [&](int x, int y, const Eigen::Vector3d& d, Hit* hit) {
    if (o.reference_raycast) return world.Cast(origin, d, visible, hit);
    NearestQuadSearch search;
    for (const ScreenTiles::Entry* e = quad_tiles.begin(x, y); e != quad_tiles.end(x, y); ++e) {
      if (e->min_distance > search.t) break;  // this quad and the rest are farther
      search.Test(quads[e->item], e->item, origin, d, kMinDistance);
    }
    // Rays with a zero direction component take QuadBvh's path (World::NearestQuad).
    const bool regular = std::abs(d.x()) > 1e-300 && std::abs(d.y()) > 1e-300 && std::abs(d.z()) > 1e-300;
    world.ReportQuad(search, regular, origin, d, kMinDistance, hit);
    for (const ScreenTiles::Entry* e = people_tiles.begin(x, y); e != people_tiles.end(x, y); ++e)
      if (!(e->min_distance > hit->t)) IntersectCylinder(visible[e->item], origin, d, kMinDistance, hit);
    return hit->hit();
  };
  const double pixel_angle = 1.0 / camera.fx;
  for (int y = row_begin; y < row_end; ++y)
    for (int x = 0; x < w; ++x) {
      const Eigen::Vector3d d = (R * camera.Ray(x + 0.5, y + 0.5)).normalized();
      Hit hit;
      Eigen::Vector3f color = Eigen::Vector3f::Zero();
      if (cast(x, y, d, &hit)) color = Shade(world, hit, d, pixel_angle, o.shading);
      WritePixel(size_t(y) * w + x, color, hit, hit.hit() ? hit.t * d.dot(R.col(2)) : 0.0, o, out);
    }
}

}  // namespace locforge::sim

#include "people.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace locforge::sim {
namespace {

// The point at arc length s along a polyline whose segments have lengths `seg`.
Eigen::Vector2d PointAtArc(const std::vector<Eigen::Vector2d>& path, const std::vector<double>& seg, double s) {
  for (size_t i = 1; i < path.size(); ++i) {
    if (s <= seg[i - 1] && seg[i - 1] > 0) return path[i - 1] + (path[i] - path[i - 1]) * (s / seg[i - 1]);
    s -= seg[i - 1];
  }
  return path.back();
}

}  // namespace

Crowd::Crowd(std::vector<Person> people) : people_(std::move(people)) {
  for (const Person& p : people_) {
    std::vector<double> seg;
    double len = 0;
    for (size_t i = 1; i < p.path.size(); ++i) {
      seg.push_back((p.path[i] - p.path[i - 1]).norm());
      len += seg.back();
    }
    segment_lengths_.push_back(std::move(seg));
    path_lengths_.push_back(len);
  }
}

Eigen::Vector2d Crowd::PositionAt(int index, double t) const {
  const Person& p = people_[index];
  const double len = path_lengths_[index];
  if (len <= 0 || p.speed <= 0) return p.path.front();
  // Ping-pong along the polyline.
  double s = std::fmod(p.phase_m + p.speed * t, 2 * len);
  if (s < 0) s += 2 * len;
  return PointAtArc(p.path, segment_lengths_[index], s <= len ? s : 2 * len - s);
}

std::array<Cylinder, 2> Crowd::Cylinders(int i, const Eigen::Vector2d& c) const {
  const Person& p = people_[i];
  const double neck = 0.84 * p.height;
  return {Cylinder{c, p.radius, 0.0, neck, i, 1.0 / 6.0, 1.0},
          Cylinder{c, 0.45 * p.radius, neck, p.height, i, 0.0, 1.0 / 6.0}};
}

std::vector<Cylinder> Crowd::At(double t) const {
  std::vector<Cylinder> out;
  out.reserve(people_.size() * 2);
  for (int i = 0; i < static_cast<int>(people_.size()); ++i)
    for (const Cylinder& c : Cylinders(i, PositionAt(i, t))) out.push_back(c);
  return out;
}

Crowd MakeCrowd(const SceneSpec& spec, double density, uint64_t seed) {
  std::mt19937_64 rng(seed * 0xD1B54A32D192ED03ull + 99);
  std::uniform_real_distribution<double> u01(0, 1);
  const double area = (spec.x1 - spec.x0) * (spec.y1 - spec.y0);
  const int count = static_cast<int>(std::lround(density * area / 100.0));
  const auto neighbours = spec.walk.Neighbours();
  std::vector<Person> people;
  for (int k = 0; k < count && !spec.walk.nodes.empty(); ++k) {
    Person p;
    // A random walk of a few edges, shifted sideways into a lane.
    int node = static_cast<int>(rng() % spec.walk.nodes.size());
    int prev = -1;
    std::vector<Eigen::Vector2d> centre{spec.walk.nodes[node]};
    for (int step = 0; step < 4; ++step) {
      std::vector<int> next;  // avoid walking straight back
      for (int n : neighbours[node])
        if (n != prev) next.push_back(n);
      if (next.empty()) next = neighbours[node];
      if (next.empty()) break;
      const int choice = next[rng() % next.size()];
      prev = node;
      node = choice;
      centre.push_back(spec.walk.nodes[node]);
    }
    const double lane = (u01(rng) < 0.5 ? -1 : 1) * (1.0 + 0.4 * u01(rng));
    for (size_t i = 0; i < centre.size(); ++i) {
      // Offset perpendicular to the local direction (averaged at corners, kept simple).
      const Eigen::Vector2d dir =
          (centre[std::min(i + 1, centre.size() - 1)] - centre[i > 0 ? i - 1 : 0]).normalized();
      p.path.push_back(centre[i] + lane * Eigen::Vector2d(-dir.y(), dir.x()));
    }
    p.speed = u01(rng) < 0.15 ? 0.0 : 0.7 + 0.8 * u01(rng);
    p.phase_m = 50 * u01(rng);
    p.radius = 0.2 + 0.08 * u01(rng);
    p.height = 1.55 + 0.35 * u01(rng);
    p.texture = "clothes:" + std::to_string(rng() % 24);
    people.push_back(std::move(p));
  }
  return Crowd(std::move(people));
}

}  // namespace locforge::sim

// People: moving occluders walking back and forth along their own paths on the
// corridor graph. Each is a textured body cylinder with a head cylinder on top;
// their position is a pure function of time, so a LiDAR point or a pixel can be
// checked against the crowd at its own instant.
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_PEOPLE_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_PEOPLE_H_

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "scene.h"

namespace locforge::sim {

// A vertical cylinder at one instant.
struct Cylinder {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double radius = 0.25;
  double z0 = 0, z1 = 1.7;
  int person = -1;    // index in the crowd
  double v0 = 0, v1 = 1;  // texture v range covered (head top of texture)
};

struct Person {
  std::vector<Eigen::Vector2d> path;  // polyline walked back and forth
  double speed = 1.2;                 // m/s
  double phase_m = 0;                 // arc length at t = 0
  double radius = 0.25;
  double height = 1.75;
  std::string texture = "clothes:0";
};

class Crowd {
 public:
  Crowd() = default;
  explicit Crowd(std::vector<Person> people);

  const std::vector<Person>& people() const { return people_; }
  Eigen::Vector2d PositionAt(int person, double t) const;
  // Body and head cylinders of person `i` standing at `center` (entries 2 i
  // and 2 i + 1 of At).
  std::array<Cylinder, 2> Cylinders(int i, const Eigen::Vector2d& center) const;
  // Body and head cylinders of everyone at time t (two per person).
  std::vector<Cylinder> At(double t) const;

 private:
  std::vector<Person> people_;
  // Per person: the lengths of its path's segments, and their sum.
  std::vector<std::vector<double>> segment_lengths_;
  std::vector<double> path_lengths_;
};

// `density` people per 100 m^2 of floor, each walking a random route on the
// walk graph in a lane offset from its centreline (so pillars and turnstiles
// stay clear), plus a few standing still.
Crowd MakeCrowd(const SceneSpec& spec, double density, uint64_t seed);

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_PEOPLE_H_

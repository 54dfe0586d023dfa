// Which people a ray may hit: a uniform 2-D grid over the floor whose cells
// list the items (people, or single cylinders) whose bounding disc overlaps
// them. A ray walks the cells its xy shadow crosses, within the height band
// the people occupy and up to the nearest surface already found, and tests
// only the items listed there. The grid is conservative (discs and the ray
// segment are padded by kMargin, far more than any rounding), and returns the
// items in ascending order, so testing them gives bit for bit the nearest hit
// of testing every person, at a fraction of the cost in a crowd.
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_PEOPLE_GRID_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_PEOPLE_GRID_H_

#include <Eigen/Core>
#include <vector>

namespace locforge::sim {

class PeopleGrid {
 public:
  // A vertical cylinder's footprint over some time span: every point of the
  // item lies within `radius` of `center` (xy) and in [z0, z1].
  struct Bound {
    Eigen::Vector2d center = Eigen::Vector2d::Zero();
    double radius = 0;
    double z0 = 0, z1 = 0;
  };
  static constexpr double kMargin = 0.01;  // metres of padding against rounding

  // Item i is bounds[i]; `cell_m` is the side of a grid cell.
  explicit PeopleGrid(const std::vector<Bound>& bounds, double cell_m = 1.0);

  // The items the segment o + t d, t in [t0, t1] (d unit; t1 may be +inf),
  // may meet, in ascending order without repeats, into `out` (cleared first).
  void Candidates(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t0, double t1,
                  std::vector<int>* out) const;

  int num_items() const { return num_items_; }

 private:
  int num_items_ = 0;
  Eigen::Vector2d lo_ = Eigen::Vector2d::Zero();  // corner of cell (0, 0)
  double cell_ = 1, z0_ = 0, z1_ = 0;             // cell side; height band of all items
  int nx_ = 0, ny_ = 0;
  std::vector<int> cell_start_;  // items of cell (x, y): items_[cell_start_[c] .. cell_start_[c + 1]), c = y nx + x
  std::vector<int> items_;
};

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_PEOPLE_GRID_H_

// Which quads a camera's pixels may see: the quads projected once per image
// into tiles of kTile x kTile pixels, each tile listing the quads whose
// projection (bounding rectangle, padded by kMarginPx) may cover one of its
// pixel centres, nearest first by a lower bound of their distance. A pixel's
// ray then tests its tile's quads until the next one cannot be nearer than
// the hit found: the nearest-quad search of primary rays without a tree walk.
// Quads reaching behind the camera's image plane go into every tile.
#ifndef LOCFORGE_SIM_SCREEN_QUADS_H_
#define LOCFORGE_SIM_SCREEN_QUADS_H_

#include <Eigen/Core>
#include <vector>

#include "camera_rig.h"
#include "locforge/pose.h"
#include "raycast.h"

namespace locforge::sim {

class ScreenQuads {
 public:
  static constexpr int kTile = 8;
  static constexpr double kMarginPx = 2;

  // Tiles covering pixel rows [row_begin, row_end) of `camera` at `T_world_camera`.
  ScreenQuads(const std::vector<Quad>& quads, const PinholeCamera& camera, const Pose& T_world_camera,
              int row_begin, int row_end);

  // The nearest quad along the unit ray d of pixel (x, y) from the camera
  // centre o, with t in (t_min, +inf), and its ties.
  NearestQuadSearch Nearest(int x, int y, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min) const;

  double MeanQuadsPerTile() const;

 private:
  struct Entry {
    double min_distance;  // lower bound of the distance to any point of the quad
    int quad;
  };
  const std::vector<Quad>& quads_;
  int tiles_x_ = 0, tile_y0_ = 0, tiles_y_ = 0;
  std::vector<int> tile_start_;  // entries of tile (tx, ty): entries_[tile_start_[i] .. tile_start_[i + 1])
  std::vector<Entry> entries_;
};

}  // namespace locforge::sim

#endif  // LOCFORGE_SIM_SCREEN_QUADS_H_

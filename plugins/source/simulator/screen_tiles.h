// What a camera's pixels may see: items (quads, people) projected once per
// image into tiles of kTile x kTile pixels. Each tile lists the items whose
// projection (the bounding rectangle of their hull's corners, padded by
// kMarginPx) may cover one of its pixel centres, with a lower bound of their
// distance from the camera; items reaching behind the image plane go into
// every tile, items wholly behind the camera into none. A pixel's ray then
// tests its tile's items instead of walking a tree or a grid.
#ifndef LOCFORGE_PLUGINS_SOURCE_SIMULATOR_SCREEN_TILES_H_
#define LOCFORGE_PLUGINS_SOURCE_SIMULATOR_SCREEN_TILES_H_

#include <Eigen/Core>
#include <vector>

#include "camera_rig.h"
#include "locforge/pose.h"

namespace locforge::sim {

class ScreenTiles {
 public:
  static constexpr int kTile = 8;
  static constexpr double kMarginPx = 2;
  struct Entry {
    double min_distance;  // no point of the item is nearer to the camera centre
    int item;
  };

  // Tiles covering pixel rows [row_begin, row_end) of `camera` at `T_world_camera`.
  ScreenTiles(const PinholeCamera& camera, const Pose& T_world_camera, int row_begin, int row_end);

  // Item `item` lies in the convex hull of the world points `corners`.
  void Add(int item, const Eigen::Vector3d* corners, int count);
  // Builds the tiles' lists: by min_distance (then item) when `nearest_first`,
  // else by item.
  void Finish(bool nearest_first);

  // The list of the tile holding pixel (x, y).
  const Entry* begin(int x, int y) const { return entries_.data() + tile_start_[Tile(x, y)]; }
  const Entry* end(int x, int y) const { return entries_.data() + tile_start_[Tile(x, y) + 1]; }

 private:
  struct Span {
    int item, tx0, tx1, ty0, ty1;
    double min_distance;
  };
  size_t Tile(int x, int y) const { return static_cast<size_t>(y / kTile - tile_y0_) * tiles_x_ + x / kTile; }

  PinholeCamera camera_;
  Eigen::Matrix3d R_camera_world_;
  Eigen::Vector3d origin_;
  int row_begin_ = 0, row_end_ = 0;
  int tiles_x_ = 0, tile_y0_ = 0, tiles_y_ = 0;
  std::vector<Span> spans_;
  std::vector<int> tile_start_;  // entries of tile i: entries_[tile_start_[i] .. tile_start_[i + 1])
  std::vector<Entry> entries_;
};

}  // namespace locforge::sim

#endif  // LOCFORGE_PLUGINS_SOURCE_SIMULATOR_SCREEN_TILES_H_

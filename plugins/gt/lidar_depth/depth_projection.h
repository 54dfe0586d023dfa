// Depth maps from a LiDAR map (paper section 3, Figure 6): the map's points
// projected into a posed camera, each point splatted as a disc of its
// footprint (point_radius_m at its depth). Two passes, as in surface
// splatting: a z-buffer of the discs finds the visible surface (the map is a
// surface sampled every few centimetres: the discs of a wall cover the wall
// and hide what lies behind it), then the discs within blend_depth_m of it
// average their depths, weighted by closeness to their centre.
#ifndef LOCFORGE_PLUGINS_GT_LIDAR_DEPTH_DEPTH_PROJECTION_H_
#define LOCFORGE_PLUGINS_GT_LIDAR_DEPTH_DEPTH_PROJECTION_H_

#include <Eigen/Core>

#include <string>
#include <vector>

#include "locforge/camera.h"
#include "locforge/pose.h"

namespace locforge::depth {

struct DepthProjectionOptions {
  // Radius of the surface patch a map point stands for (m): about the map's
  // voxel size (slam/pose_graph map_voxel_m = 0.05), so that the discs of a
  // surface leave no gap the surfaces behind could show through.
  double point_radius_m = 0.05;
  double min_depth_m = 0.3;   // nearer points are dropped (the platform itself)
  double max_depth_m = 30;    // farther points are dropped
  int max_splat_radius_px = 12;  // caps a near point's disc
  double blend_depth_m = 0.1;    // discs this far behind the nearest one are averaged with it (same surface)
  bool Check(std::string* why) const;
};

// A z-depth map: width x height, row-major, z in the camera frame (m), 0 = none.
struct DepthMap {
  int width = 0, height = 0;
  std::vector<float> z;
};

// Points of a map bucketed in square cells of the xy plane, so that a camera
// only visits the cells within its range.
class MapIndex {
 public:
  MapIndex(std::vector<Eigen::Vector3f> points, double cell_m = 2.0);
  // Calls fn(point) for each point of the cells within `range` of `centre` (xy).
  template <class Fn>
  void ForEachNear(const Eigen::Vector3d& centre, double range, Fn&& fn) const {
    const int x0 = Cell(centre.x() - range - origin_.x()), x1 = Cell(centre.x() + range - origin_.x());
    const int y0 = Cell(centre.y() - range - origin_.y()), y1 = Cell(centre.y() + range - origin_.y());
    for (int cy = std::max(0, y0); cy <= std::min(ny_ - 1, y1); ++cy)
      for (int cx = std::max(0, x0); cx <= std::min(nx_ - 1, x1); ++cx) {
        const size_t c = static_cast<size_t>(cy) * nx_ + cx;
        for (uint32_t k = start_[c]; k < start_[c + 1]; ++k) fn(points_[k]);
      }
  }
  size_t size() const { return points_.size(); }

 private:
  int Cell(double v) const { return static_cast<int>(std::floor(v / cell_m_)); }
  double cell_m_;
  Eigen::Vector2d origin_;
  int nx_ = 0, ny_ = 0;
  std::vector<Eigen::Vector3f> points_;  // sorted by cell
  std::vector<uint32_t> start_;          // per cell, into points_ (+1 end)
};

// The depth map of `camera` at world-to-camera pose `T_camera_world`.
DepthMap ProjectMap(const MapIndex& map, const Camera& camera, const Pose& T_camera_world,
                    const DepthProjectionOptions& options = {});

// Errors of `estimate` against `reference` over the pixels where both have a
// depth (and `keep`, when given, is non-zero there).
// |estimate - reference| is kept as a histogram of 0.5 mm bins up to 5 m (the
// last bin holds everything beyond), so millions of images fit in memory.
struct DepthErrors {
  static constexpr double kBinM = 0.0005;
  static constexpr int kBins = 10000;
  size_t compared = 0;         // pixels with both depths
  size_t reference_valid = 0;  // pixels with a reference depth (and keep)
  size_t nearer = 0, farther = 0;  // compared pixels off by more than the tolerance, each way
  std::vector<uint64_t> histogram = std::vector<uint64_t>(kBins + 1, 0);
  void Add(double abs_error_m);
  void Merge(const DepthErrors& other);
  // Upper edge of the bin holding quantile q (0..1) of the errors; NaN when empty.
  double Quantile(double q) const;
  // Fraction (0..1) of the compared pixels within `m` (to the bin).
  double FractionWithin(double m) const;
  double Coverage() const { return reference_valid ? static_cast<double>(compared) / reference_valid : 0; }
};
// nearer / farther: the estimate is nearer / farther than the reference by
// more than tolerance_m (an occluder the reference does not have, e.g. a
// person the LiDAR saw; a surface seen through a gap).
void AccumulateDepthErrors(const DepthMap& estimate, const DepthMap& reference, const std::vector<uint8_t>* keep,
                           double tolerance_m, DepthErrors* errors);

// kapture .depth files: width x height float32, row-major, little endian.
std::string EncodeDepth(const DepthMap& depth);
// Throws InputError naming `file` when the size does not match.
DepthMap DecodeDepth(const std::string& bytes, int width, int height, const std::string& file);

}  // namespace locforge::depth

#endif  // LOCFORGE_PLUGINS_GT_LIDAR_DEPTH_DEPTH_PROJECTION_H_

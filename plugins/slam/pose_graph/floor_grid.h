// Top-down evidence of what a set of LiDAR scans saw, to judge whether two
// maps can be the same place under a frame hypothesis: the cells where the
// scans' returns lie (occupied) and the cells their rays crossed before any
// return (free). A wrong join puts one map's walls into the other's free
// space (a wall across a corridor) all along the overlap; a right one does so
// only where people stood or objects moved between the recordings.
//
// Two dimensions suffice for a wheeled platform on a level floor: returns in
// a height band above the floor (walls, shop fronts, pillars, people), rays
// from the platform's origin, one per azimuth bin to its nearest return.
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_FLOOR_GRID_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_FLOOR_GRID_H_

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "cloud.h"
#include "locforge/pose.h"

namespace locforge::lidar {

struct FloorGridOptions {
  double cell_m = 0.1;               // side of a grid cell
  double min_height_m = 0.3;         // band of returns used, rig frame: above the floor's returns ...
  double max_height_m = 1.8;         // ... and below ceilings and overhangs
  double azimuth_bin_deg = 0.5;      // one ray per bin, to its nearest return in the band
  double max_range_m = 30;           // farther returns neither occupy nor free cells
  int min_scans_occupied = 2;        // a cell is structure when returns from this many scans fall in it ...
  // ... and one of them reaches this band (rig frame): walls, pillars and shop
  // fronts do, people (< 2 m) do not, so people who stood still in one
  // recording are no evidence against a frame; ceilings stay above it.
  double tall_min_height_m = 2.0;
  double tall_max_height_m = 2.6;
  int min_scans_free = 2;            // a cell is free when this many scans' rays crossed it and none hit it
  // Occupied cells within this distance of the other map's returns count as
  // agreeing: the drift of two maps not yet optimised together.
  double agreement_margin_m = 0.3;
  // Structure in the other map's free space counts as conflicting only in
  // connected pieces at least this long (bounding-box diagonal): a person who
  // stood still, or a bag, is smaller; a wall that a wrong frame puts across
  // a corridor is not.
  double min_conflict_extent_m = 0;
  bool Check(std::string* why = nullptr) const;
};

// What one map saw, in its own frame.
class FloorGrid {
 public:
  // `extent`: the xy box every added scan's rays lie in (positions +- max_range).
  FloorGrid(const FloorGridOptions& options, const Eigen::AlignedBox2d& extent);

  // A scan in the rig frame, taken at T_world_rig (world = the grid's frame).
  void AddScan(const Cloud& scan, const Pose& T_world_rig);
  // Call once after the last AddScan: classifies the cells.
  void Finish();

  enum class State : uint8_t { kUnknown, kFree, kOccupied };
  // State of the cell holding world point p (kUnknown outside the grid).
  State At(const Eigen::Vector2d& p) const;
  // Whether p lies within agreement_margin_m of a cell any scan hit.
  bool NearOccupied(const Eigen::Vector2d& p) const;
  // Centres of the structure cells (occupied by min_scans_occupied scans, tall).
  const std::vector<Eigen::Vector2d>& structure() const { return structure_; }
  // Integer cell coordinates of a point (for grouping cells into pieces).
  Eigen::Vector2i CellOf(const Eigen::Vector2d& p) const;
  int scans() const { return scans_; }
  const FloorGridOptions& options() const { return o_; }

 private:
  bool Index(const Eigen::Vector2d& p, int* i) const;
  FloorGridOptions o_;
  Eigen::Vector2d origin_;
  int width_ = 0, height_ = 0;
  std::vector<uint16_t> hit_scans_, crossed_scans_;
  std::vector<uint8_t> tall_;
  std::vector<int32_t> last_hit_, last_crossed_;  // scan that last counted the cell (once per scan)
  std::vector<uint8_t> near_occupied_;
  std::vector<Eigen::Vector2d> structure_;
  int scans_ = 0;
  bool finished_ = false;
};

// How the structure of `x`, moved into y's frame by T_y_x, sits in `y`.
struct FloorAgreement {
  int64_t agreeing = 0;     // structure cells near y's returns
  int64_t conflicting = 0;  // structure cells in y's free space, in pieces of min_conflict_extent_m or more
  int64_t unseen = 0;       // structure cells y did not observe
  int64_t small_conflicts = 0;  // structure cells in y's free space in smaller pieces (people, objects moved)
  // conflicting / (agreeing + conflicting); 0 without overlap.
  double ConflictFraction() const;
};
FloorAgreement CompareFloors(const FloorGrid& x, const FloorGrid& y, const Pose& T_y_x);

// Both directions of a frame hypothesis T_a_b (b's frame into a's).
struct JoinEvidence {
  FloorAgreement b_in_a, a_in_b;
  // The worse of the two directions' conflict fractions, and the smaller overlap.
  double Conflict() const;
  int64_t Agreeing() const;
};
JoinEvidence EvaluateJoin(const FloorGrid& a, const FloorGrid& b, const Pose& T_a_b);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_FLOOR_GRID_H_

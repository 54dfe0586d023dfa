// One sequence's SLAM before any join (slam.h, Slam::RunWithinParts): its
// keyframes with their clouds, its pose graph (sequential, odometry and loop
// edges) optimised, the initial estimate, its counters. The stage
// slam/sequences computes one per sequence as its own item (shardable, one
// Slurm array task each); slam/pose_graph reads them all and runs only the
// joins (Slam::AdoptParts), so a floor's sequences run on as many nodes as
// it has sequences.
//
// File: binary, little endian, written atomically (one file per sequence):
//   "LFSLAMPART" u32 version
//   str sequence, u8 manual, u32 n_params, n x (str key, str value)
//   u32 n_keyframes, n x (i64 timestamp, f64 travelled, cloud, cloud rough)
//     cloud: u64 n_points, n x 3 f32, u8 has_normals, [n x 3 f32]
//   nodes (per keyframe: pose), before (per keyframe: pose)
//     pose: 7 f64 (qw qx qy qz tx ty tz)
//   u32 n_edges, n x (i32 from, i32 to, pose, 36 f64 information, u8 loss, f64 loss_scale, u8 loop)
//   u32 n_loops, n x (i32, i32)
//   stats: i32 x5 counters, i64 loop_tests, u32 n x (str sequence, f64 yaw scale),
//          f64 initial_cost, f64 final_cost, i32 iterations, u32 n x (str step, f64 seconds)
// Keyframe ids in the file are the part's own (0..n-1, time order).
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_PART_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_PART_H_

#include <string>
#include <utility>
#include <vector>

#include "keyframes.h"
#include "locforge/fs.h"
#include "pose_graph.h"
#include "slam_stats.h"

namespace locforge::lidar {

struct SlamPart {
  std::string sequence;
  bool manual = false;  // placed by initial_poses
  // The stage options it was computed with (ParamSchema::Format): the join
  // refuses parts made with other options than its own.
  std::vector<std::pair<std::string, std::string>> params;
  std::vector<Keyframe> keyframes;  // ids 0..n-1; context not stored (computed from the cloud on reading)
  PoseGraph graph, before;          // optimised, and the initial estimate
  std::vector<std::pair<int, int>> loops;  // loop edges accepted (min id, max id)
  // The counts and times of the part's own steps (those of joins are 0;
  // summary.report is not stored).
  SlamStats stats;
};

std::string EncodeSlamPart(const SlamPart& part);
// Throws InputError naming `name` and the field when the bytes are not a
// part of this version (truncated, another format, values out of range).
// Every keyframe's place descriptor (context) is computed from its cloud.
// `keep_clouds` false: the full clouds are not kept, each keyframe names
// its cloud's place instead (cloud_file = `name`, cloud_offset).
SlamPart DecodeSlamPart(const std::string& bytes, const std::string& name, bool keep_clouds = true);

void WriteSlamPart(const fs::path& path, const SlamPart& part);  // atomic
SlamPart ReadSlamPart(const fs::path& path, bool keep_clouds = true);
// The full cloud at `offset` of a part file (Keyframe::cloud_offset).
Cloud ReadPartCloud(const fs::path& path, uint64_t offset);

// The file of a sequence's part in a slam/sequences output folder ("" -> "_").
std::string PartFileName(const std::string& sequence);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_SLAM_PART_H_

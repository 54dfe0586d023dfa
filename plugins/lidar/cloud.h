// Point clouds of the LiDAR stages: xyz (float) with optional per-point time,
// PCD read/write, voxel downsampling. Kept small on purpose; the shared
// locforge/pointcloud_io.h readers can replace ReadPcd once they land.
#ifndef LOCFORGE_PLUGINS_LIDAR_CLOUD_H_
#define LOCFORGE_PLUGINS_LIDAR_CLOUD_H_

#include <Eigen/Core>
#include <vector>

#include "locforge/fs.h"
#include "locforge/pose.h"
#include "locforge/registration.h"

namespace locforge::lidar {

// times: seconds after the record timestamp; empty when unknown.
using Cloud = locforge::PointCloud;

// Reads a PCD (ascii or binary; fields x y z required, `time` F32/F64 kept if present).
// Throws InputError naming the file and the field.
Cloud ReadPcd(const fs::path& path);
// Writes a binary PCD with fields x y z (atomic).
void WritePcd(const fs::path& path, const Cloud& cloud);
// Writes an ascii PLY with vertex x y z (atomic).
void WritePly(const fs::path& path, const Cloud& cloud);

// One point (the centroid) per occupied voxel of side `voxel` (m); times dropped.
Cloud VoxelDownsample(const Cloud& cloud, double voxel);
// Applies T to every point.
void Transform(const Pose& T, Cloud* cloud);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_LIDAR_CLOUD_H_

// Reading and writing point clouds: PLY (ascii, binary little endian) and PCD
// (ascii, binary; v0.7 as written by PCL and by the simulator).
//
// Fields understood (others are skipped, any numeric type is converted):
//   position   x y z
//   normals    nx ny nz (PLY) or normal_x normal_y normal_z (PCL/PCD)
//   time       time / timestamp / t (seconds per point)
//   intensity  intensity / scalar_intensity
//   ring       ring
// Errors throw InputError naming the file, the header line (when it applies)
// and the field. Writes are atomic (fs.h).
#ifndef LOCFORGE_POINTCLOUD_IO_H_
#define LOCFORGE_POINTCLOUD_IO_H_

#include <cstdint>
#include <filesystem>
#include <vector>

#include "locforge/registration.h"  // PointCloud

namespace locforge {

// Per-point attributes beside PointCloud; each empty or one per point.
struct PointAttributes {
  std::vector<float> intensity;
  std::vector<uint16_t> ring;
};

enum class PointCloudEncoding { kAscii, kBinary };

// By extension (.ply / .pcd, case-insensitive); `attributes` may be null.
PointCloud ReadPointCloud(const std::filesystem::path& file, PointAttributes* attributes = nullptr);
void WritePointCloud(const std::filesystem::path& file, const PointCloud& cloud,
                     PointCloudEncoding encoding = PointCloudEncoding::kBinary,
                     const PointAttributes* attributes = nullptr);

PointCloud ReadPly(const std::filesystem::path& file, PointAttributes* attributes = nullptr);
PointCloud ReadPcd(const std::filesystem::path& file, PointAttributes* attributes = nullptr);
// PLY: x y z [nx ny nz] [intensity] [ring] [time(double)].
void WritePly(const std::filesystem::path& file, const PointCloud& cloud,
              PointCloudEncoding encoding = PointCloudEncoding::kBinary,
              const PointAttributes* attributes = nullptr);
// PCD v0.7: x y z [normal_x normal_y normal_z] [intensity] [ring(U2)] [time(F8)]
// — with intensity, ring and times this is the simulator's layout.
void WritePcd(const std::filesystem::path& file, const PointCloud& cloud,
              PointCloudEncoding encoding = PointCloudEncoding::kBinary,
              const PointAttributes* attributes = nullptr);

// The same from/to memory; `name` is used in error messages.
PointCloud DecodePly(const std::string& bytes, const std::string& name,
                     PointAttributes* attributes = nullptr);
PointCloud DecodePcd(const std::string& bytes, const std::string& name,
                     PointAttributes* attributes = nullptr);
std::string EncodePly(const PointCloud& cloud, PointCloudEncoding encoding,
                      const PointAttributes* attributes = nullptr);
std::string EncodePcd(const PointCloud& cloud, PointCloudEncoding encoding,
                      const PointAttributes* attributes = nullptr);

}  // namespace locforge

#endif  // LOCFORGE_POINTCLOUD_IO_H_

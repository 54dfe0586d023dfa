// COLMAP 3.8 sparse models (cameras, images, points3D) in COLMAP's text and
// binary formats, byte for byte as src/base/reconstruction.cc of 3.8 writes
// them.
//
// Records are kept in file order (COLMAP writes its hash maps in their own
// order), so reading a model and writing it back reproduces the same bytes.
// Like COLMAP, the writers normalise the image quaternion, except one that is
// already unit to rounding, which is written as stored (normalising is not
// idempotent in floating point: re-normalising would drift by an ulp per
// read-write cycle). The readers keep the numbers as stored.
//
// A model is held in memory as COLMAP itself does; the large, streamable
// parts of a COLMAP project (features, matches) live in the database
// (database.h).
#ifndef LOCFORGE_COLMAP_MODEL_H_
#define LOCFORGE_COLMAP_MODEL_H_

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "locforge/camera.h"
#include "locforge/pose.h"

namespace locforge::colmap {

// COLMAP's id types (src/util/types.h): camera_t and image_t are uint32,
// point2D_t uint32, point3D_t uint64.
using CameraId = uint32_t;
using ImageId = uint32_t;
using Point2DIdx = uint32_t;
using Point3DId = uint64_t;
// "No 3D point": -1 in the text format, uint64 max in the binary one.
constexpr Point3DId kInvalidPoint3DId = std::numeric_limits<Point3DId>::max();

struct ModelCamera {
  CameraId camera_id = 0;
  Camera camera;  // model (a COLMAP id, never kUnknown), width, height, params
};

struct Point2D {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();  // pixels, see convention.h
  Point3DId point3d_id = kInvalidPoint3DId;
  bool HasPoint3D() const { return point3d_id != kInvalidPoint3DId; }
};

struct ModelImage {
  ImageId image_id = 0;
  Eigen::Vector4d qvec{1, 0, 0, 0};  // (qw, qx, qy, qz) of R_camera_world
  Eigen::Vector3d tvec = Eigen::Vector3d::Zero();
  CameraId camera_id = 0;
  std::string name;
  std::vector<Point2D> points2d;

  // World-to-camera pose T_camera_world (pose.h convention).
  Pose CameraFromWorld() const;
  void SetCameraFromWorld(const Pose& T_camera_world);
  // Points2D that observe a 3D point.
  size_t NumPoints3D() const;
};

struct TrackElement {
  ImageId image_id = 0;
  Point2DIdx point2d_idx = 0;
  bool operator==(const TrackElement& o) const {
    return image_id == o.image_id && point2d_idx == o.point2d_idx;
  }
};

struct ModelPoint3D {
  Point3DId point3d_id = 0;
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  std::array<uint8_t, 3> color{0, 0, 0};
  double error = -1.0;  // mean reprojection error in pixels (COLMAP: -1 = unknown)
  std::vector<TrackElement> track;
};

struct Reconstruction {
  std::vector<ModelCamera> cameras;   // file order
  std::vector<ModelImage> images;     // file order; all registered
  std::vector<ModelPoint3D> points3d; // file order

  // Lookups by linear scan (build a map for many queries); null when absent.
  const ModelCamera* FindCamera(CameraId id) const;
  const ModelImage* FindImage(ImageId id) const;
  const ModelImage* FindImageByName(const std::string& name) const;

  // COLMAP's header statistics.
  size_t NumObservations() const;          // sum of track lengths
  double MeanObservationsPerImage() const; // over images, 0 when none
  double MeanTrackLength() const;          // 0 when no points

  // Cross-checks ids: every image's camera exists, every track element
  // points to an existing image and point2D that refers back to the point,
  // and ids are unique. Returns "" or the first problem found.
  std::string Validate() const;
};

enum class ModelFormat { kText, kBinary };

// Reads a model folder. ReadModel picks the format as COLMAP does: binary
// when cameras.bin, images.bin and points3D.bin exist, else text. Throws
// InputError naming the file, the line (text) or byte offset (binary) and
// the field.
Reconstruction ReadModel(const std::filesystem::path& dir);
Reconstruction ReadModelText(const std::filesystem::path& dir);
Reconstruction ReadModelBinary(const std::filesystem::path& dir);
// True when `dir` holds a complete model in this format.
bool HasModel(const std::filesystem::path& dir, ModelFormat format);

// Writes cameras, images and points3D (.txt or .bin) into `dir` (created),
// each file atomically.
void WriteModel(const Reconstruction& model, const std::filesystem::path& dir,
                ModelFormat format);
void WriteModelText(const Reconstruction& model, const std::filesystem::path& dir);
void WriteModelBinary(const Reconstruction& model, const std::filesystem::path& dir);

// COLMAP's NormalizeQuaternion: q / |q|, or identity when |q| == 0.
Eigen::Vector4d NormalizeQvec(const Eigen::Vector4d& qvec);

}  // namespace locforge::colmap

#endif  // LOCFORGE_COLMAP_MODEL_H_

// The COLMAP 3.8 SQLite database (src/base/database.cc of 3.8): the same
// tables, index, CREATE statements, pragmas and user_version (3800), so the
// `colmap` executable accepts a database made here, and blobs laid out as
// COLMAP lays them out:
//   cameras.params            double[num_params]
//   keypoints.data            float32[rows x cols], row-major, cols 2, 4 or 6
//                             (x, y[, scale, orientation | a11, a12, a21, a22])
//   descriptors.data          uint8[rows x cols] (cols 128 for SIFT)
//   matches.data              uint32[rows x 2] (point2D idx in image1, image2)
//   two_view_geometries.data  uint32[rows x 2], inlier matches
//   two_view_geometries F,E,H double[3x3] row-major; qvec double[4]; tvec double[3]
// A pair of images is one row keyed by pair_id = image_id1 * 2147483647 +
// image_id2 with image_id1 < image_id2; writing the pair the other way round
// swaps the match columns (and inverts the geometry), as COLMAP does.
//
// Reading tolerates the older schema without qvec/tvec (kapture toolbox
// exports). SQLite stays private: no sqlite3.h here.
#ifndef LOCFORGE_COLMAP_DATABASE_H_
#define LOCFORGE_COLMAP_DATABASE_H_

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "locforge/camera.h"
#include "locforge/colmap/model.h"
#include "locforge/pose.h"

namespace locforge::colmap {

using PairId = uint64_t;
// COLMAP's kMaxNumImages (std::numeric_limits<int32_t>::max()).
constexpr uint64_t kMaxNumImages = 2147483647;

// True when COLMAP stores (image_id1, image_id2) swapped, i.e. id1 > id2.
inline bool SwapImagePair(ImageId image_id1, ImageId image_id2) { return image_id1 > image_id2; }
PairId ImagePairToPairId(ImageId image_id1, ImageId image_id2);
// Returns (smaller id, larger id).
std::pair<ImageId, ImageId> PairIdToImagePair(PairId pair_id);

struct DbCamera {
  CameraId camera_id = 0;
  Camera camera;
  bool prior_focal_length = false;
};

struct DbImage {
  ImageId image_id = 0;
  std::string name;
  CameraId camera_id = 0;
  // prior_qw..prior_tz; NULL columns (no prior) read as nullopt.
  std::optional<Eigen::Vector4d> prior_qvec;
  std::optional<Eigen::Vector3d> prior_tvec;
};

// rows x cols, row-major.
struct KeypointsBlob {
  uint32_t rows = 0;
  uint32_t cols = 0;  // 2, 4 or 6
  std::vector<float> data;
  float at(size_t r, size_t c) const { return data[r * cols + c]; }
};

struct DescriptorsBlob {
  uint32_t rows = 0;
  uint32_t cols = 0;
  std::vector<uint8_t> data;
};

// Matches between image_id1 and image_id2 in that order: (idx1, idx2) rows.
using FeatureMatches = std::vector<std::pair<Point2DIdx, Point2DIdx>>;

// COLMAP's TwoViewGeometry::ConfigurationType.
enum class TwoViewConfig : int {
  kUndefined = 0,
  kDegenerate = 1,
  kCalibrated = 2,
  kUncalibrated = 3,
  kPlanar = 4,
  kPanoramic = 5,
  kPlanarOrPanoramic = 6,
  kWatermark = 7,
  kMultiple = 8,
};

struct TwoViewGeometry {
  int config = static_cast<int>(TwoViewConfig::kUndefined);
  FeatureMatches inlier_matches;
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d E = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  Eigen::Vector4d qvec{1, 0, 0, 0};  // relative pose image1 -> image2
  Eigen::Vector3d tvec = Eigen::Vector3d::Zero();
  // Same geometry seen from image2 to image1 (COLMAP's Invert()).
  TwoViewGeometry Inverted() const;
};

class Database {
 public:
  enum class Mode {
    kReadOnly,   // the file must exist
    kReadWrite,  // the file must exist; missing COLMAP tables are created
    kCreate,     // created if absent, then as kReadWrite
  };

  // Opens (or creates) a database. Throws InputError (not a COLMAP
  // database, unreadable) or Error.
  explicit Database(const std::filesystem::path& path, Mode mode = Mode::kReadOnly);
  ~Database();
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  const std::filesystem::path& path() const { return path_; }

  // ---- reading (streaming: one row in memory at a time for the For* calls)
  size_t NumCameras() const;
  size_t NumImages() const;
  size_t NumKeypointRows() const;   // sum of rows over images
  size_t NumMatchedPairs() const;   // rows of the matches table
  size_t NumTwoViewGeometries() const;
  bool HasPoseColumnsInTwoViewGeometries() const { return has_tvg_pose_; }

  std::vector<DbCamera> ReadCameras() const;
  std::vector<DbImage> ReadImages() const;  // by image_id
  std::optional<KeypointsBlob> ReadKeypoints(ImageId image_id) const;
  std::optional<DescriptorsBlob> ReadDescriptors(ImageId image_id) const;
  // Matches as (idx in image_id1, idx in image_id2), whatever the stored order.
  std::optional<FeatureMatches> ReadMatches(ImageId image_id1, ImageId image_id2) const;
  std::optional<TwoViewGeometry> ReadTwoViewGeometry(ImageId image_id1, ImageId image_id2) const;

  // Visit rows in key order; the callback may stop early by returning false.
  void ForEachKeypoints(const std::function<bool(ImageId, const KeypointsBlob&)>& fn) const;
  void ForEachDescriptors(const std::function<bool(ImageId, const DescriptorsBlob&)>& fn) const;
  // (image_id1 < image_id2, matches in that order)
  void ForEachMatches(
      const std::function<bool(ImageId, ImageId, const FeatureMatches&)>& fn) const;
  void ForEachTwoViewGeometry(
      const std::function<bool(ImageId, ImageId, const TwoViewGeometry&)>& fn) const;

  // ---- writing (each call is its own statement; wrap many in a
  // Transaction or use DatabaseWriter, which batches them)
  // Returns the camera_id: `camera.camera_id` when use_camera_id, else a new one.
  CameraId WriteCamera(const DbCamera& camera, bool use_camera_id);
  ImageId WriteImage(const DbImage& image, bool use_image_id);
  void WriteKeypoints(ImageId image_id, const KeypointsBlob& keypoints);
  void WriteDescriptors(ImageId image_id, const DescriptorsBlob& descriptors);
  void WriteMatches(ImageId image_id1, ImageId image_id2, const FeatureMatches& matches);
  void WriteTwoViewGeometry(ImageId image_id1, ImageId image_id2, const TwoViewGeometry& tvg);

  // The schema as sqlite_master holds it ("sql" of every table and index,
  // by name, one per line): compare with a database made by `colmap`.
  std::string SchemaSql() const;
  // PRAGMA user_version (3800 for COLMAP 3.8).
  int UserVersion() const;
  // Runs raw SQL; for tools and tests (COLMAP's tables must keep their layout).
  void Execute(const std::string& sql);

  void BeginTransaction();
  void CommitTransaction();
  void RollbackTransaction();

  struct Impl;  // opaque (SQLite handles)

 private:
  std::unique_ptr<Impl> impl_;
  std::filesystem::path path_;
  bool has_tvg_pose_ = true;
};

// Writes through a Database in transactions of `batch_size` writes (one
// transaction per row is orders of magnitude slower in SQLite). Finish()
// commits the last batch; destroyed without Finish() it rolls the open
// batch back.
class DatabaseWriter {
 public:
  explicit DatabaseWriter(Database* db, size_t batch_size = 512);
  ~DatabaseWriter();
  DatabaseWriter(const DatabaseWriter&) = delete;
  DatabaseWriter& operator=(const DatabaseWriter&) = delete;

  CameraId WriteCamera(const DbCamera& camera, bool use_camera_id);
  ImageId WriteImage(const DbImage& image, bool use_image_id);
  void WriteKeypoints(ImageId image_id, const KeypointsBlob& keypoints);
  void WriteDescriptors(ImageId image_id, const DescriptorsBlob& descriptors);
  void WriteMatches(ImageId image_id1, ImageId image_id2, const FeatureMatches& matches);
  void WriteTwoViewGeometry(ImageId image_id1, ImageId image_id2, const TwoViewGeometry& tvg);
  void Finish();

 private:
  void Step();
  Database* db_;
  size_t batch_size_;
  size_t pending_ = 0;
  bool open_ = false;
};

}  // namespace locforge::colmap

#endif  // LOCFORGE_COLMAP_DATABASE_H_

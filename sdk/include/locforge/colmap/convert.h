// kapture <-> COLMAP 3.8: a kapture folder to a COLMAP database + sparse
// model, and back. Pixel coordinates follow convention.h; poses pose.h (both
// formats store world-to-camera, so poses pass unchanged, except that rig
// poses are composed per camera on export).
//
// Ids are stable: camera_id = 1 + rank of the camera sensor id, image_id =
// 1 + rank of the image name (records_camera image_path), both sorted; on
// import the kapture toolbox's naming is used (sensor "cam_%05d" of the
// camera_id, timestamp = image_id), and image names are kept.
#ifndef LOCFORGE_COLMAP_CONVERT_H_
#define LOCFORGE_COLMAP_CONVERT_H_

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "locforge/colmap/database.h"
#include "locforge/colmap/model.h"

namespace locforge::kapture {
class Kapture;
}

namespace locforge::colmap {

struct ExportOptions {
  // kapture keypoints type to export (a folder of reconstruction/keypoints);
  // "" = the only one present (an error when there are several).
  std::string keypoints_type;
  // Descriptors type; "" = the one whose keypoints_type matches, if any.
  // COLMAP stores uint8 descriptors only: other dtypes are skipped (noted).
  std::string descriptors_type;
  bool export_descriptors = true;
  bool export_matches = true;
  // Also store the matches as verified two-view geometries (config below,
  // F/E/H zero), which COLMAP's mappers and point_triangulator read.
  bool export_two_view_geometries = true;
  int two_view_config = static_cast<int>(TwoViewConfig::kUncalibrated);
  // points3d + observations -> points3D with tracks; false leaves the model
  // point-less (the input of `colmap point_triangulator`).
  bool export_points3d = true;
  // Write pose priors (prior_qw..prior_tz) of posed images in the database.
  bool write_pose_priors = true;
  ModelFormat model_format = ModelFormat::kText;
  // Replace an existing database file (else refused).
  bool overwrite = false;
  // Database writes per transaction.
  size_t batch_size = 256;

  bool Check(std::string* why) const;
};

struct ExportReport {
  int64_t cameras = 0;
  int64_t images = 0;            // in the database
  int64_t posed_images = 0;      // in the model
  int64_t keypoint_images = 0;
  int64_t descriptor_images = 0;
  int64_t match_pairs = 0;
  int64_t matches = 0;
  int64_t points3d = 0;
  int64_t observations = 0;
  double mean_reprojection_error = 0;  // over exported points, pixels
  std::string keypoints_type;
  std::vector<std::string> notes;  // skipped items, with reasons (capped)
};

// Writes the COLMAP database `database` (atomically: a temp file renamed
// at the end) and, when `model_dir` is not empty, the sparse model of the
// posed images. Throws InputError on bad kapture data, Error otherwise.
ExportReport ExportToColmap(const kapture::Kapture& kapture, const std::filesystem::path& database,
                            const std::filesystem::path& model_dir,
                            const ExportOptions& options = {});

struct ImportOptions {
  // The kapture keypoints/descriptors type written (folder and name).
  std::string features_type = "SIFT";
  bool import_keypoints = true;
  bool import_descriptors = true;
  bool import_matches = true;
  // Matches from two_view_geometries (geometrically verified inliers) when
  // the database has them, as the kapture toolbox does; false = the raw
  // `matches` table.
  bool verified_matches = true;
  bool import_points3d = true;
  // Allow writing into an existing non-empty folder.
  bool overwrite = false;

  bool Check(std::string* why) const;
};

struct ImportReport {
  int64_t cameras = 0;
  int64_t images = 0;
  int64_t posed_images = 0;
  int64_t keypoint_images = 0;
  int64_t descriptor_images = 0;
  int64_t match_pairs = 0;
  int64_t points3d = 0;
  int64_t observations = 0;
  std::vector<std::string> notes;
};

// Writes a kapture folder from a COLMAP database and/or model (either path
// may be empty, not both). Cameras come from the model when given (refined
// intrinsics), else from the database; images and features from the
// database; poses and points from the model.
ImportReport ImportFromColmap(const std::filesystem::path& database,
                              const std::filesystem::path& model_dir,
                              const std::filesystem::path& kapture_out,
                              const ImportOptions& options = {});

// Writes a model's 3D points as kapture reconstruction/points3d.txt and
// observations.txt under `kapture_root` (atomically), in the model's point
// order; observations name images by the model's image names and keypoints
// of type `keypoints_type`. Returns the number of observations written.
int64_t WriteKapturePoints(const Reconstruction& model, const std::string& keypoints_type,
                           const std::filesystem::path& kapture_root);

// "cam_00001" for camera_id 1, as the kapture toolbox names them.
std::string KaptureSensorIdOf(CameraId camera_id);

}  // namespace locforge::colmap

#endif  // LOCFORGE_COLMAP_CONVERT_H_

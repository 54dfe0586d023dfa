// Running COLMAP 3.8 tools on kapture artifacts: filling a database (cameras,
// images, keypoints, matches stored as verified two-view geometries), the
// Mapper options of the paper, and the registered queries back as kapture.
// Used by the stages that run the colmap executable (mapper/, localizer/,
// pipeline/, gt/spline_ba).
#ifndef LOCFORGE_COLMAP_KAPTURE_DATABASE_H_
#define LOCFORGE_COLMAP_KAPTURE_DATABASE_H_

#include <map>
#include <string>
#include <vector>

#include "locforge/colmap/database.h"
#include "locforge/colmap/model.h"
#include "locforge/colmap/run.h"
#include "locforge/kapture/kapture.h"
#include "locforge/params.h"
#include "locforge/plugin.h"

namespace locforge::colmap {

// The one keypoints type of a features artifact, or `wanted` when given.
std::string KeypointsType(const kapture::Kapture& features, const std::string& wanted);

struct DbImages {
  std::map<std::string, ImageId> id_of;           // image name -> image_id
  std::map<std::string, CameraId> camera_of;      // sensor id -> camera_id
  std::map<ImageId, int64_t> num_keypoints;
};

// Adds one camera per camera sensor used by records_camera, and one image
// (with its keypoints x, y) per record. Returns the ids given.
DbImages AddImages(const kapture::Kapture& dataset, const kapture::Kapture& features,
                   const std::string& keypoints_type, DatabaseWriter* writer);

// Adds matches (and the same as verified two-view geometries) for every pair
// of the matches artifact whose two images are in `ids`; `only_with` (when
// not empty) keeps the pairs with one image in it. Returns the pair count.
int64_t AddMatches(const kapture::Kapture& matches, const std::string& keypoints_type,
                   const std::map<std::string, ImageId>& ids,
                   const std::map<std::string, ImageId>& only_with,
                   DatabaseWriter* writer);

// "--Mapper.NAME VALUE" pairs.
void AddMapperOption(std::vector<std::string>* args, const std::string& name, double value);

// Writes the query poses COLMAP's image_registrator put into `model` as a
// kapture under `out` (query sensors, rigs, trajectories.txt) and every record
// it did not register to out/failures.txt (never replaced by another pose).
// Returns the number registered.
int WriteRegisteredQueries(const Reconstruction& model, const kapture::Kapture& query,
                           const std::vector<kapture::DataRecord>& records,
                           const std::filesystem::path& out);

// How every stage of this plugin runs a colmap tool: its log in the node's
// output folder (colmap_TOOL.log), the stage's timeout, and the host's cancel
// (Ctrl-C) stops the child.
RunOptions RunOptionsFor(RunContext& ctx, const std::string& tool, double timeout_s);

// Intrinsics stay fixed in every tool: --Mapper.ba_refine_{focal_length,
// principal_point,extra_params} 0.
void AddFixedIntrinsics(std::vector<std::string>* args);

// COLMAP 3.8 Mapper options in the order of the paper's supplementary table.
struct MapperParams {
  int min_num_matches;
  int init_min_num_inliers;
  int abs_pose_min_num_inliers;
  double abs_pose_min_inlier_ratio;
  int ba_local_max_num_iterations;
  double abs_pose_max_error;
  double filter_max_reproj_error;
  // COLMAP skips a feature seen in only two images (a two-view track) when
  // it triangulates; a sparse map (few, far-apart images) is mostly such tracks.
  bool ignore_two_view_tracks = true;
  void AddTo(std::vector<std::string>* args) const;
};
// The paper's values: point_triangulator (mapping) and image_registrator
// (localization); the stages' defaults and the vocab-tree pipeline use them.
inline constexpr MapperParams kPaperTriangulator{15, 100, 30, 0.25, 25, 12, 4};
inline constexpr MapperParams kPaperRegistrator{4, 4, 4, 0.05, 50, 20, 12};

// The Mapper options of point_triangulator / image_registrator, defaulting to
// the paper's values for that tool (kPaperTriangulator / kPaperRegistrator).
template <const MapperParams& kDefaults>
struct MapperOptions {
  int min_num_matches = kDefaults.min_num_matches;
  int init_min_num_inliers = kDefaults.init_min_num_inliers;
  int abs_pose_min_num_inliers = kDefaults.abs_pose_min_num_inliers;
  double abs_pose_min_inlier_ratio = kDefaults.abs_pose_min_inlier_ratio;
  int ba_local_max_num_iterations = kDefaults.ba_local_max_num_iterations;
  double abs_pose_max_error = kDefaults.abs_pose_max_error;
  double filter_max_reproj_error = kDefaults.filter_max_reproj_error;
  bool ignore_two_view_tracks = kDefaults.ignore_two_view_tracks;
  std::string keypoints_type;  // empty = the features' only keypoints type
  double timeout_s = 0;        // kill colmap after this many seconds (0: never)
  static void Declare(ParamSchema<MapperOptions>& s) {
    using O = MapperOptions;
    s.Add("min_num_matches", &O::min_num_matches, "Mapper.min_num_matches").Min(1);
    s.Add("init_min_num_inliers", &O::init_min_num_inliers, "Mapper.init_min_num_inliers").Min(1);
    s.Add("abs_pose_min_num_inliers", &O::abs_pose_min_num_inliers,
          "Mapper.abs_pose_min_num_inliers").Min(3);
    s.Add("abs_pose_min_inlier_ratio", &O::abs_pose_min_inlier_ratio,
          "Mapper.abs_pose_min_inlier_ratio").Range(0, 1);
    s.Add("ba_local_max_num_iterations", &O::ba_local_max_num_iterations,
          "Mapper.ba_local_max_num_iterations").Min(0);
    s.Add("abs_pose_max_error", &O::abs_pose_max_error, "Mapper.abs_pose_max_error (px)").Min(0.01);
    s.Add("filter_max_reproj_error", &O::filter_max_reproj_error,
          "Mapper.filter_max_reproj_error (px)").Min(0.01);
    s.Add("ignore_two_view_tracks", &O::ignore_two_view_tracks,
          "Mapper.tri_ignore_two_view_tracks: leave features seen by only two images untriangulated");
    s.Add("keypoints_type", &O::keypoints_type, "keypoints type; empty = the only one");
    s.Add("timeout_s", &O::timeout_s, "kill colmap after this many seconds (0: never)").Min(0).NoCacheKey();
  }
  MapperParams Mapper() const {
    return {min_num_matches, init_min_num_inliers, abs_pose_min_num_inliers,
            abs_pose_min_inlier_ratio, ba_local_max_num_iterations, abs_pose_max_error,
            filter_max_reproj_error, ignore_two_view_tracks};
  }
};
using TriangulatorOptions = MapperOptions<kPaperTriangulator>;
using RegistratorOptions = MapperOptions<kPaperRegistrator>;

}  // namespace locforge::colmap

#endif  // LOCFORGE_COLMAP_KAPTURE_DATABASE_H_

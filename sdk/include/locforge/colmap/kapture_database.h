// Filling a COLMAP 3.8 database from kapture artifacts (cameras, images,
// keypoints, matches stored as verified two-view geometries), shared by the
// triangulator and the registrator stages.
#ifndef LOCFORGE_PLUGINS_COLMAP_STAGES_COLMAP_DB_H_
#define LOCFORGE_PLUGINS_COLMAP_STAGES_COLMAP_DB_H_

#include <map>
#include <string>
#include <vector>

#include "locforge/colmap/database.h"
#include "locforge/colmap/model.h"
#include "locforge/colmap/run.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"

namespace locforge::colmap_stages {

// The one keypoints type of a features artifact, or `wanted` when given.
std::string KeypointsType(const kapture::Kapture& features, const std::string& wanted);

struct DbImages {
  std::map<std::string, colmap::ImageId> id_of;           // image name -> image_id
  std::map<std::string, colmap::CameraId> camera_of;      // sensor id -> camera_id
  std::map<colmap::ImageId, int64_t> num_keypoints;
};

// Adds one camera per camera sensor used by records_camera, and one image
// (with its keypoints x, y) per record. Returns the ids given.
DbImages AddImages(const kapture::Kapture& dataset, const kapture::Kapture& features,
                   const std::string& keypoints_type, colmap::DatabaseWriter* writer);

// Adds matches (and the same as verified two-view geometries) for every pair
// of the matches artifact whose two images are in `ids`; `only_with` (when
// not empty) keeps the pairs with one image in it. Returns the pair count.
int64_t AddMatches(const kapture::Kapture& matches, const std::string& keypoints_type,
                   const std::map<std::string, colmap::ImageId>& ids,
                   const std::map<std::string, colmap::ImageId>& only_with,
                   colmap::DatabaseWriter* writer);

// "--Mapper.NAME VALUE" pairs.
void AddMapperOption(std::vector<std::string>* args, const std::string& name, double value);

// Writes the query poses COLMAP's image_registrator put into `model` as a
// kapture under `out` (query sensors, rigs, trajectories.txt) and every record
// it did not register to out/failures.txt (never replaced by another pose).
// Returns the number registered.
int WriteRegisteredQueries(const colmap::Reconstruction& model, const kapture::Kapture& query,
                           const std::vector<kapture::DataRecord>& records,
                           const std::filesystem::path& out);

// How every stage of this plugin runs a colmap tool: its log in the node's
// output folder (colmap_TOOL.log), the stage's timeout, and the host's cancel
// (Ctrl-C) stops the child.
colmap::RunOptions RunOptionsFor(RunContext& ctx, const std::string& tool, double timeout_s);

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
  void AddTo(std::vector<std::string>* args) const;
};
// The paper's values: point_triangulator (mapping) and image_registrator
// (localization); the stages' defaults and the vocab-tree pipeline use them.
inline constexpr MapperParams kPaperTriangulator{15, 100, 30, 0.25, 25, 12, 4};
inline constexpr MapperParams kPaperRegistrator{4, 4, 4, 0.05, 50, 20, 12};

}  // namespace locforge::colmap_stages

#endif  // LOCFORGE_PLUGINS_COLMAP_STAGES_COLMAP_DB_H_

// localizer/pnp: in-process absolute pose per query (or per rig of query
// cameras at one timestamp) from query-to-map matches and the map's 3D points.
#include <chrono>
#include <map>
#include <mutex>
#include <sstream>
#include <unordered_map>

#include "absolute_pose.h"
#include "correspondences.h"
#include "point_uncertainty.h"
#include "query_results.h"
#include "locforge/kapture/kapture.h"
#include "locforge/kapture/rigs.h"
#include "locforge/plugin.h"

namespace locforge::localizer {

using namespace ::locforge::localization;  // the library this stage wires
namespace {

namespace kp = locforge::kapture;

struct PnPOptions {
  double max_error_px = 12.0;  // RANSAC inlier threshold in pixels.
  double confidence = 0.9999;  // RANSAC stopping confidence.
  int min_iterations = 100;    // RANSAC iterations at least.
  int max_iterations = 10000;  // RANSAC iterations at most.
  int min_inliers = 10;        // Fewer inliers: the query fails.
  double min_inlier_ratio = 0.0;  // Lower inlier ratio: the query fails.
  double cauchy_scale_px = 0.5;   // Cauchy loss scale of the refinement (the final one's floor)
  double cauchy_noise_factor = 0;  // > 0: final refinement's scale >= this x the inliers' noise sigma
  int64_t seed = 0;               // RANSAC seed (deterministic).
  bool rig_queries = false;       // Query cameras of one rig at one timestamp share a pose.
  double point_covariance_scale = 0;  // > 0, with map_images: residuals weighed by their point's uncertainty.
  std::string keypoints_type;     // Query keypoints type; "" = the only one.

  static void Declare(ParamSchema<PnPOptions>& s) {
    s.Add("max_error_px", &PnPOptions::max_error_px, "RANSAC inlier threshold, pixels").Min(0.01);
    s.Add("confidence", &PnPOptions::confidence, "RANSAC stopping confidence").Range(0.5, 0.999999);
    s.Add("min_iterations", &PnPOptions::min_iterations, "RANSAC iterations at least").Min(1);
    s.Add("max_iterations", &PnPOptions::max_iterations, "RANSAC iterations at most").Min(1);
    s.Add("min_inliers", &PnPOptions::min_inliers, "fewer inliers: the query fails").Min(3);
    s.Add("min_inlier_ratio", &PnPOptions::min_inlier_ratio, "lower inlier ratio: the query fails").Range(0, 1);
    s.Add("cauchy_scale_px", &PnPOptions::cauchy_scale_px, "Cauchy loss scale of the Ceres refinement, pixels").Min(1e-3);
    s.Add("cauchy_noise_factor", &PnPOptions::cauchy_noise_factor,
          "> 0: the final refinement's Cauchy scale is at least this times the inliers' measured noise "
          "(per-axis sigma, pixels); 0: cauchy_scale_px alone").Range(0, 10);
    s.Add("seed", &PnPOptions::seed, "RANSAC random seed").Min(0);
    s.Add("rig_queries", &PnPOptions::rig_queries, "query cameras of one rig at one timestamp share one rig pose");
    s.Add("keypoints_type", &PnPOptions::keypoints_type, "query keypoints type; empty = the only one");
    s.Add("point_covariance_scale", &PnPOptions::point_covariance_scale,
          "with the map_images input: each residual of the refinement whitened by its 3D point's "
          "triangulation covariance as the query sees it, times this (the map's keypoint noise "
          "relative to the query's; 0: every point exact)").Range(0, 100);
  }
  bool Check(std::string* why) const { return ToRansac().Check(why); }
  RansacOptions ToRansac() const {
    RansacOptions r;
    r.max_error_px = max_error_px;
    r.confidence = confidence;
    r.min_iterations = min_iterations;
    r.max_iterations = max_iterations;
    r.min_inliers = min_inliers;
    r.min_inlier_ratio = min_inlier_ratio;
    r.seed = static_cast<uint64_t>(seed);
    r.refine.cauchy_scale_px = cauchy_scale_px;
    r.refine.noise_factor = cauchy_noise_factor;
    r.refine.point_covariance_scale = point_covariance_scale;
    return r;
  }
};

struct QueryImage {
  Timestamp timestamp = 0;
  std::string device;
  std::string image;
};

// One item: a query image, or the images of one rig at one timestamp.
struct QueryItem {
  std::string device;  // trajectory device: the camera, or the rig
  Timestamp timestamp = 0;
  std::vector<QueryImage> images;
};

std::string FeatureTypeOf(const kp::Kapture& k, kp::FeatureKind kind, const std::string& wanted,
                          const std::string& what) {
  if (!wanted.empty()) return wanted;
  const auto sets = k.FeatureSets(kind);
  if (sets.size() != 1)
    throw InputError(k.root().string(), 0, what,
                     std::to_string(sets.size()) + " feature types found; set keypoints_type");
  return sets.front().type;
}

class PnPLocalizer : public PerItemStage<PnPOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"localizer",
            "pnp",
            "P3P/EPnP LO-RANSAC + Cauchy-robust Ceres refinement per query (fixed intrinsics, "
            "optional rig queries); failed queries are listed in failures.txt, never guessed",
            {{"query", "kapture.dataset", "query sensors, rigs and records_camera"},
             {"query_features", "kapture.local_features", "query keypoints"},
             {"map", "kapture.reconstruction", "map points3d + observations"},
             {"matches", "kapture.matches", "query-to-map matches"},
             {"map_images", "kapture.dataset",
              "map image poses and cameras: each point's residual weighed by how well its views "
              "triangulate it", LF_PORT_OPTIONAL}},
            {{"trajectories", "kapture.trajectories",
              "estimated query poses (+ failures.txt, localization_stats.csv)"}}};
    meta.version = "1.5.0";  // 1.5.0: optional map_images: residuals weighed by point uncertainty
    return meta;
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override {
    Load(ctx);
    std::vector<std::string> out;
    for (const auto& [name, item] : items_) out.push_back(name);
    return out;
  }

  void ProcessItem(RunContext& ctx, const std::string& name) override {
    Load(ctx);
    const QueryItem& item = items_.at(name);
    const auto start = std::chrono::steady_clock::now();
    CorrespondenceSet correspondences;
    std::vector<RigCamera> cameras;
    for (const auto& image : item.images) {
      const kp::Sensor* sensor = query_->sensors().Find(image.device);
      if (!sensor || !sensor->camera)
        throw InputError("sensors/sensors.txt", 0, image.device, "query camera not found");
      const Camera& camera = *sensor->camera;
      RigCamera rc;
      rc.focal = 0.5 * (camera.fx() + camera.fy());
      if (item.device != image.device) {
        const kp::Rig* rig = query_->rigs().Find(item.device);
        rc.camera_from_rig = rig->Find(image.device)->sensor_from_rig;
      }
      const int camera_index = static_cast<int>(cameras.size());
      cameras.push_back(rc);
      AddCorrespondences(image.image, camera, camera_index, &correspondences);
    }
    const std::vector<Correspondence>& cs = correspondences.correspondences();
    RansacOptions ransac = options().ToRansac();
    ransac.seed ^= std::hash<std::string>{}(name);
    AbsolutePoseResult r = EstimateAbsolutePose(cs, cameras, ransac);
    QueryOutcome outcome;
    outcome.success = r.success;
    outcome.device_from_world = r.rig_from_world;
    outcome.failure = r.failure;
    outcome.stats = {double(cs.size()), double(r.num_inliers), double(r.iterations),
                     std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()};
    WriteQueryResult(ctx.output_dir(), name, outcome);
  }

  void Finalize(RunContext& ctx) override {
    Load(ctx);
    std::vector<QueryItemInfo> items;
    for (const auto& [name, item] : items_) items.push_back({name, item.timestamp, item.device});
    const int ok = WriteLocalizationOutputs(ctx.output_dir(), items,
                                            {"correspondences", "inliers", "iterations", "seconds"},
                                            query_->sensors(), query_->rigs());
    ctx.Info("localized " + std::to_string(ok) + " of " + std::to_string(items_.size()) +
             " queries");
  }

 private:
  void AddCorrespondences(const std::string& image, const Camera& camera, int camera_index,
                          CorrespondenceSet* cs) {
    kp::FeatureArray keypoints;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      keypoints = features_->ReadKeypoints(keypoints_type_, image);
    }
    auto pairs = map_images_of_.find(image);
    if (pairs == map_images_of_.end()) return;
    for (const std::string& map_image : pairs->second) {
      auto observed = observations_.find(map_image);
      if (observed == observations_.end()) continue;
      std::vector<kp::Match> matches;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        matches = matches_->ReadMatches(matches_type_, image, map_image);
      }
      for (const kp::Match& m : matches) {
        const int64_t q = static_cast<int64_t>(m.index1);
        auto point = observed->second.find(static_cast<int64_t>(m.index2));
        if (point == observed->second.end()) continue;
        if (q < 0 || q >= keypoints.rows)
          throw InputError(matches_->MatchesPath(matches_type_, image, map_image).string(), 0,
                           "index", "keypoint index " + std::to_string(q) + " out of range");
        const Eigen::Vector2d pixel(keypoints.At(q, 0), keypoints.At(q, 1));
        for (const int64_t id : point->second) {
          const kp::Point3d& p = points_[id];
          cs->Add(camera_index, q, id, camera.Unproject(pixel).hnormalized(),
                  Eigen::Vector3d(p.x, p.y, p.z),
                  covariances_.empty() ? Eigen::Matrix3d::Zero() : covariances_[id]);
        }
      }
    }
  }

  void Load(RunContext& ctx) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (loaded_) return;
    query_ = std::make_unique<kp::Kapture>(ctx.Input("query"));
    features_ = std::make_unique<kp::Kapture>(ctx.Input("query_features"));
    matches_ = std::make_unique<kp::Kapture>(ctx.Input("matches"));
    keypoints_type_ = FeatureTypeOf(*features_, kp::FeatureKind::kKeypoints,
                                    options().keypoints_type, "keypoints_type");
    const auto types = matches_->MatchesTypes();
    if (types.empty()) throw InputError(ctx.Input("matches").string(), 0, "matches", "no matches");
    matches_type_ = std::find(types.begin(), types.end(), keypoints_type_) != types.end()
                        ? keypoints_type_ : types.front();
    // Queries.
    std::map<std::pair<Timestamp, std::string>, QueryItem> by_rig;
    for (const auto& r : query_->ReadDataRecords(kp::kSensorCamera)) {
      QueryImage image{r.timestamp, r.device_id, r.path};
      const kp::Rig* rig = options().rig_queries ? query_->rigs().RigOf(r.device_id) : nullptr;
      if (rig) {
        QueryItem& item = by_rig[{r.timestamp, rig->id}];
        item.device = rig->id;
        item.timestamp = r.timestamp;
        item.images.push_back(image);
      } else {
        items_[r.path] = QueryItem{r.device_id, r.timestamp, {image}};
      }
    }
    for (auto& [key, item] : by_rig)
      items_["rig_" + item.device + "/" + std::to_string(key.first)] = std::move(item);
    std::unordered_map<std::string, bool> is_query;
    for (const auto& [name, item] : items_)
      for (const auto& image : item.images) is_query[image.image] = true;
    // Query-to-map pairs.
    for (const auto& [a, b] : matches_->MatchPairs(matches_type_)) {
      if (is_query.count(a) && !is_query.count(b)) map_images_of_[a].push_back(b);
      if (is_query.count(b) && !is_query.count(a)) map_images_of_[b].push_back(a);
    }
    // Map points and who observes them.
    kp::Kapture map(ctx.Input("map"));
    points_ = map.points3d();
    for (const auto& entry : map.observations()) {
      if (entry.point3d_id < 0 || entry.point3d_id >= static_cast<int64_t>(points_.size()))
        throw InputError("reconstruction/observations.txt", 0, "point3d_id",
                         "point " + std::to_string(entry.point3d_id) + " not in points3d.txt");
      for (const auto& [image, feature] : entry.features)
        observations_[image][feature].push_back(entry.point3d_id);
    }
    if (options().point_covariance_scale > 0) {
      if (ctx.Inputs("map_images").empty())
        throw ParamError("point_covariance_scale needs the `map_images` input (the map's poses and cameras)");
      LoadCovariances(ctx.Input("map_images"), map);
    }
    ctx.Info(std::to_string(items_.size()) + " queries, " + std::to_string(points_.size()) +
             " map points, " + std::to_string(map_images_of_.size()) + " queries with matches");
    loaded_ = true;
  }

  // Each map point's triangulation covariance from the views that observe it.
  void LoadCovariances(const fs::path& map_images, const kp::Kapture& reconstruction) {
    const kp::Kapture map(map_images);
    std::unordered_map<std::string, MapView> view_of;
    for (const auto& r : map.ReadDataRecords(kp::kSensorCamera)) {
      const auto pose = map.DevicePose(r.timestamp, r.device_id);
      const kp::Sensor* sensor = map.sensors().Find(r.device_id);
      if (!pose || !sensor || !sensor->camera) continue;
      view_of[r.path] = {pose->Center(), 0.5 * (sensor->camera->fx() + sensor->camera->fy())};
    }
    covariances_.assign(points_.size(), Eigen::Matrix3d::Zero());
    for (const auto& entry : reconstruction.observations()) {
      std::vector<MapView> views;
      for (const auto& [image, feature] : entry.features) {
        const auto view = view_of.find(image);
        if (view == view_of.end())
          throw InputError(map_images.string(), 0, image, "observed map image has no pose or camera");
        views.push_back(view->second);
      }
      const kp::Point3d& p = points_[entry.point3d_id];
      covariances_[entry.point3d_id] = TriangulationCovariance(Eigen::Vector3d(p.x, p.y, p.z), views);
    }
  }

  std::mutex mutex_;
  bool loaded_ = false;
  std::unique_ptr<kp::Kapture> query_, features_, matches_;
  std::string keypoints_type_, matches_type_;
  std::map<std::string, QueryItem> items_;
  std::unordered_map<std::string, std::vector<std::string>> map_images_of_;
  std::vector<kp::Point3d> points_;
  std::vector<Eigen::Matrix3d> covariances_;  // per point; empty without map_images
  std::unordered_map<std::string, std::unordered_map<int64_t, std::vector<int64_t>>> observations_;
};

}  // namespace
LOCFORGE_REGISTER_STAGE(PnPLocalizer)

}  // namespace locforge::localizer

// gt/lidar_depth (paper Figure 6): the LiDAR map projected into every posed
// image as a kapture depth map, the scene coordinates ESAC-style methods train
// on and a dense hand-off to MVS. Per image, so it shards.
#include <algorithm>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>

#include "depth_projection.h"
#include "locforge/fs.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "locforge/pointcloud_io.h"
#include "locforge/registration.h"

namespace locforge::gt {

namespace {

namespace kp = locforge::kapture;

struct LidarDepthOptions {
  depth::DepthProjectionOptions projection;
  std::string map_file = "map.pcd";  // The map inside the lidar_map input.

  static void Declare(ParamSchema<LidarDepthOptions>& s) {
    using O = LidarDepthOptions;
    s.Add("point_radius_m", &O::projection, &depth::DepthProjectionOptions::point_radius_m,
          "surface radius each map point is splatted with (m; ~0.7 x the map voxel)").Min(1e-4);
    s.Add("min_depth_m", &O::projection, &depth::DepthProjectionOptions::min_depth_m, "nearer points are dropped (m)")
        .Min(0.01);
    s.Add("max_depth_m", &O::projection, &depth::DepthProjectionOptions::max_depth_m, "farther points are dropped (m)")
        .Min(0.1);
    s.Add("max_splat_radius_px", &O::projection, &depth::DepthProjectionOptions::max_splat_radius_px,
          "largest disc of a near point (px)").Range(0, 200);
    s.Add("map_file", &O::map_file, "the point cloud in the lidar_map input (PCD or PLY, the camera poses' frame)");
  }
  bool Check(std::string* why) const {
    if (map_file.empty() || fs::path(map_file).is_absolute() || map_file.find("..") != std::string::npos)
      return *why = "map_file must be a relative path inside the lidar_map input", false;
    return projection.Check(why);
  }
};

std::string DepthPath(const std::string& image) { return fs::path(image).replace_extension(".depth").generic_string(); }
std::string DepthSensorId(const std::string& camera) { return camera + "_depth"; }

class LidarDepthStage : public PerItemStage<LidarDepthOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"gt", "lidar_depth",
                      "The LiDAR map projected into every posed image with a z-buffer over splatted points "
                      "(paper Fig. 6): kapture depth records, one float32 .depth map per image",
                      {{"images", "kapture.dataset", "posed images: sensors, camera poses, records_camera.txt (e.g. the gt output)"},
                       {"lidar_map", "kapture.trajectories", "slam/pose_graph output: map.pcd in the poses' frame"}},
                      {{"depth", "kapture.dataset",
                        "sensors (<camera>_depth), trajectories, records_depth.txt, records_data/<image>.depth, depth.md"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override { return kp::Kapture(ctx.Input("images")).CameraImages(); }

  void ProcessItem(RunContext& ctx, const std::string& image) override {
    const kp::Kapture& images = Images(ctx);
    const kp::DataRecord* record = RecordOf(images, image);
    const kp::Sensor* sensor = images.sensors().Find(record->device_id);
    if (!sensor || !sensor->camera)
      throw InputError((images.root() / kp::layout::kSensors).string(), 0, record->device_id, "not a camera");
    const auto pose = images.DevicePose(record->timestamp, record->device_id);
    if (!pose) return;  // unposed images get no depth (Finalize counts them)
    const depth::DepthMap d = depth::ProjectMap(Map(ctx), *sensor->camera, *pose, options().projection);
    WriteFileAtomic(ctx.output_dir() / kp::layout::kRecordsData / DepthPath(image), depth::EncodeDepth(d));
  }

  void Finalize(RunContext& ctx) override {
    const kp::Kapture& images = Images(ctx);
    const fs::path out = ctx.output_dir();
    kp::Sensors sensors;
    kp::Trajectories trajectories;
    std::vector<kp::DataRecord> records;
    size_t unposed = 0;
    for (const auto& r : images.ReadDataRecords(kp::kSensorCamera)) {
      const auto pose = images.DevicePose(r.timestamp, r.device_id);
      if (!pose) {
        ++unposed;
        continue;
      }
      const kp::Sensor* camera = images.sensors().Find(r.device_id);
      const std::string id = DepthSensorId(r.device_id);
      if (!sensors.Contains(id)) sensors.Add(kp::MakeCameraSensor(id, camera->name, *camera->camera, kp::kSensorDepth));
      trajectories.Set(r.timestamp, id, *pose);
      records.push_back({r.timestamp, id, DepthPath(r.path)});
      // Every map is there and whole (its size; reading them all back would
      // cost as much as writing them: 20 MB per full-resolution image).
      const fs::path file = out / kp::layout::kRecordsData / records.back().path;
      const uintmax_t expected = static_cast<uintmax_t>(camera->camera->width) * camera->camera->height * sizeof(float);
      std::error_code ec;
      if (fs::file_size(file, ec) != expected || ec)
        throw InputError(file.string(), 0, "depth", "missing or not " + std::to_string(expected) +
                                                        " bytes (rerun the node with --force)");
    }
    kp::WriteSensors(out / kp::layout::kSensors, sensors);
    kp::WriteTrajectories(out / kp::layout::kTrajectories, trajectories);
    kp::WriteRecords(out / kp::layout::RecordsFile(kp::kSensorDepth), kp::RecordKind::kDepth, records);
    std::ostringstream md;
    md << "# Depth from the LiDAR map\n\n" << records.size() << " depth maps (" << unposed
       << " images without a pose skipped); coverage and errors against a reference: eval/depth.\n";
    WriteFileAtomic(out / "depth.md", md.str());
    ctx.Info(md.str());
  }

 private:
  const kp::Kapture& Images(RunContext& ctx) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!images_) {
      images_.emplace(ctx.Input("images"));
      for (const auto& r : images_->ReadDataRecords(kp::kSensorCamera)) records_[r.path] = r;
    }
    return *images_;
  }
  const kp::DataRecord* RecordOf(const kp::Kapture& images, const std::string& image) {
    const auto it = records_.find(image);
    if (it == records_.end())
      throw InputError((images.root() / kp::layout::RecordsFile(kp::kSensorCamera)).string(), 0, image, "no such record");
    return &it->second;
  }
  const depth::MapIndex& Map(RunContext& ctx) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!map_) {
      const fs::path file = SafeJoin(ctx.Input("lidar_map"), options().map_file, "map_file");
      if (!fs::exists(file)) throw InputError(file.string(), 0, "map_file", "no point cloud in the lidar_map input");
      map_.emplace(ReadPointCloud(file).points);
      ctx.Info("LiDAR map: " + std::to_string(map_->size()) + " points");
    }
    return *map_;
  }
  std::mutex mutex_;
  std::optional<kp::Kapture> images_;
  std::map<std::string, kp::DataRecord> records_;
  std::optional<depth::MapIndex> map_;
};

}  // namespace

LOCFORGE_REGISTER_STAGE(LidarDepthStage)

}  // namespace locforge::gt

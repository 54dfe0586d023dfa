// gt/images: the camera part of a recording with poses from another node
// (the LiDAR half), as a kapture dataset the feature and matching stages read.
#include <random>
#include <sstream>

#include "locforge/plugin.h"
#include "sfm_gt_common.h"
#include "locforge/kapture/io.h"

namespace locforge::gt {

using namespace ::locforge::sfm_gt;  // the library this stage wires

namespace {

struct ImagesOptions {
  std::string dataset;  // The recording (records_camera.txt + images).
  static void Declare(ParamSchema<ImagesOptions>& s) {
    s.Add("dataset", &ImagesOptions::dataset,
          "kapture recording with records_camera.txt and the images (or wire the recording input)").Path();
  }
};

class ImagesStage : public Stage<ImagesOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"gt", "images",
            "The images of a recording (records_camera.txt, images hard-linked) with the sensors, "
            "rigs and poses of another node (e.g. the LiDAR half), as one kapture dataset",
            {{"poses", "kapture.trajectories", "sensors.txt, rigs.txt, trajectories.txt"},
             {"recording", "kapture.dataset", "the recording, instead of the dataset parameter", LF_PORT_OPTIONAL}},
            {{"dataset", "kapture.dataset", "cameras, poses, records_camera.txt, records_data/"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using Stage::Stage;
  void Run(RunContext& ctx) override;
};

}  // namespace

void ImagesStage::Run(RunContext& ctx) {
  const auto& o = options();
  const fs::path in = ctx.Input("poses");
  const fs::path dataset = ctx.PathOrInput("gt/images", "dataset", o.dataset, "recording");
  kp::Kapture recording(dataset);
  const kp::Sensors sensors = kp::ReadSensors(in / kp::layout::kSensors);
  const kp::Trajectories poses = kp::ReadTrajectories(in / kp::layout::kTrajectories);
  std::vector<kp::DataRecord> records;
  int64_t unposed = 0;
  for (const auto& r : recording.ReadDataRecords(kp::kSensorCamera)) {
    if (!sensors.Find(r.device_id))
      throw InputError((in / kp::layout::kSensors).string(), 0, r.device_id, "camera of records_camera.txt missing");
    if (!poses.Find(r.timestamp, r.device_id)) {
      ++unposed;
      continue;
    }
    records.push_back(r);
  }
  if (records.empty())
    throw InputError((in / kp::layout::kTrajectories).string(), 0, "trajectories", "no image of " + dataset.string() + " has a pose");
  if (unposed) ctx.Warn(std::to_string(unposed) + " images without a pose left out");
  const fs::path out = ctx.output_dir();
  fs::create_directories(out / "sensors");
  kp::WriteSensors(out / kp::layout::kSensors, sensors);
  if (fs::exists(in / kp::layout::kRigs)) kp::WriteRigs(out / kp::layout::kRigs, kp::ReadRigs(in / kp::layout::kRigs));
  kp::WriteTrajectories(out / kp::layout::kTrajectories, poses);
  kp::WriteRecords(out / kp::layout::RecordsFile(kp::kSensorCamera), kp::RecordKind::kCamera, records);
  const int64_t linked = LinkRecordData(recording, records, out);
  ctx.Info(std::to_string(linked) + " images with poses");
}

LOCFORGE_REGISTER_STAGE(ImagesStage)

}  // namespace locforge::gt

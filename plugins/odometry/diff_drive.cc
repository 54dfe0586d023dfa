// odometry/diff_drive: the wheel odometry as a kapture trajectory of the rig.
#include <cmath>

#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"
#include "lidar_stages.h"

namespace locforge::lidar {

void DiffDrive::Run(RunContext& ctx) {
  const DiffDriveOptions& o = options();
  const fs::path dataset = RecordingOf(ctx, o.dataset, "odometry/diff_drive");
  const WheelOdometry odometry = WheelOdometry::FromKapture(dataset, o.Wheels());
  kapture::RecordsReader<kapture::GenericRecord> reader(dataset / kapture::layout::RecordsFile("wheel_encoder"));
  kapture::Trajectories trajectories;
  kapture::GenericRecord r;
  double next = -1e300;
  const double step = 1e6 / o.rate_hz;  // kapture timestamps in microseconds
  while (reader.Next(&r)) {
    const double t = static_cast<double>(r.timestamp);
    if (t < next) continue;
    next = t + step;
    trajectories.Set(r.timestamp, "rig", odometry.PlatformPose(t).Inverse());
  }
  kapture::WriteTrajectories(ctx.output_dir() / kapture::layout::kTrajectories, trajectories);
  ctx.Info("diff_drive: " + std::to_string(trajectories.size()) + " poses over " +
           std::to_string(odometry.num_segments()) + " segments");
}

fs::path RecordingOf(RunContext& ctx, const std::string& dataset_param, const std::string& stage) {
  if (ctx.HasInput("recording")) {
    if (!dataset_param.empty())
      throw ParamError(stage + ": the recording is given twice: as the dataset parameter (" + dataset_param +
                       ") and as the recording input; keep one");
    return ctx.Input("recording");
  }
  if (dataset_param.empty())
    throw ParamError(stage + ": no recording: set the dataset parameter (in the shipped graphs: --set dataset=DIR, "
                     "a kapture recording folder) or wire the recording input");
  return dataset_param;
}

}  // namespace locforge::lidar

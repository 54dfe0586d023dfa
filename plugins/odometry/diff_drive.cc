// odometry/diff_drive: the wheel odometry as a kapture trajectory of the rig.
#include <cmath>

#include "lidar_params.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "wheel_odometry.h"

namespace locforge::odometry {

using namespace ::locforge::lidar;  // the library this stage wires

struct DiffDriveOptions {
  std::string dataset;  // the recording (or the `recording` input): sensors/records_wheel_encoder.txt
  WheelOverrides wheels;
  double rate_hz = 10;  // output poses per second
  static void Declare(ParamSchema<DiffDriveOptions>& s) {
    using O = DiffDriveOptions;
    s.Add("dataset", &O::dataset, "Kapture recording with wheel encoder records (or wire the recording input)")
        .Path();
    DeclareWheelOverrides(s, &O::wheels);
    s.Add("rate_hz", &O::rate_hz, "Output platform poses per second").Range(0.1, 1000);
  }
};

class DiffDrive : public Stage<DiffDriveOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta{"odometry", "diff_drive",
                   "Differential-drive wheel odometry from encoder ticks (platform trajectory, device rig)",
                   {RecordingPort()},
                   {{"trajectories", "kapture.trajectories", "T_rig_odom per segment, at rate_hz"}}};
    meta.version = "0.7.0";
    return meta;
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const DiffDriveOptions& o = options();
    const fs::path dataset = RecordingOf(ctx, o.dataset, "odometry/diff_drive");
    const WheelOdometry odometry = WheelOdometry::FromKapture(dataset, o.wheels.Params());
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
};

LOCFORGE_REGISTER_STAGE(DiffDrive)

}  // namespace locforge::odometry

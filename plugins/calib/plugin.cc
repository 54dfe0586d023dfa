// The stages of kind calib; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::lidar {
LOCFORGE_DECLARE_STAGE(AddLidarToLidar);
}  // namespace locforge::lidar

namespace locforge::sfm_gt {
LOCFORGE_DECLARE_STAGE(AddPerturb);
}  // namespace locforge::sfm_gt

LOCFORGE_PLUGIN("calib", "0.6.0", "Calibration: LiDAR-LiDAR extrinsic, perturbed calibrations",
                locforge::Exported<locforge::lidar::AddLidarToLidar>,
                locforge::Exported<locforge::sfm_gt::AddPerturb>)

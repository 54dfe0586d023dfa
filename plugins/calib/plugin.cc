// The stages of kind calib. calib/lidar_to_lidar declares no version of its own (its
// declaration is in ../common/lidar/lidar_stages.h): this plugin's version
// keys its cached results.
#include "lidar_stages.h"
#include "locforge/plugin.h"

namespace locforge::sfm_gt {
LOCFORGE_DECLARE_STAGE(AddPerturb);
}  // namespace locforge::sfm_gt

LOCFORGE_PLUGIN("calib", "0.6.0", "Calibration: LiDAR-LiDAR extrinsic, perturbed calibrations",
                locforge::lidar::LidarToLidar,
                locforge::Exported<locforge::sfm_gt::AddPerturb>)

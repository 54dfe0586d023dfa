// The stages of kind slam; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::lidar {
LOCFORGE_DECLARE_STAGE(AddPoseGraphSlam);
}  // namespace locforge::lidar

LOCFORGE_PLUGIN("slam", "0.7.0", "Pose-graph LiDAR SLAM", locforge::Exported<locforge::lidar::AddPoseGraphSlam>)

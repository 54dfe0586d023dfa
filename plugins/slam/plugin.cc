// The stages of kind slam. slam/pose_graph declares no version of its own (its
// declaration is in ../common/lidar/lidar_stages.h): this plugin's version
// keys its cached results.
#include "lidar_stages.h"
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("slam", "0.6.0", "Pose-graph LiDAR SLAM",
                locforge::lidar::PoseGraphSlam)

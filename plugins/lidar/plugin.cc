// The stages of kind lidar. lidar/preprocess declares no version of its own (its
// declaration is in ../common/lidar/lidar_stages.h): this plugin's version
// keys its cached results.
#include "lidar_stages.h"
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("lidar", "0.6.0", "LiDAR scans into the platform frame: undistortion, merging, filtering",
                locforge::lidar::Preprocess)

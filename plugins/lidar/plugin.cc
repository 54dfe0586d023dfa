// The stages of kind lidar; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::lidar {
LOCFORGE_DECLARE_STAGE(AddPreprocess);
}  // namespace locforge::lidar

LOCFORGE_PLUGIN("lidar", "0.8.0", "LiDAR scans into the platform frame: undistortion, merging, filtering",
                locforge::Exported<locforge::lidar::AddPreprocess>)

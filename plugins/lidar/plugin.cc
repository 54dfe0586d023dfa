// The stages of kind lidar: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("lidar", "0.8.0", "LiDAR scans into the platform frame: undistortion, merging, filtering")

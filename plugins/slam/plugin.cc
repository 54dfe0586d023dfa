// The stages of kind slam: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("slam", "0.7.0", "Pose-graph LiDAR SLAM")

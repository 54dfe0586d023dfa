// The stages of kind gt: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("gt", "1.0.0", "SfM half of the ground truth: images with LiDAR poses, spline bundle adjustment outer loop, depth maps from the LiDAR map")

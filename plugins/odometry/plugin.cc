// The stages of kind odometry. odometry/diff_drive declares no version of its own (its
// declaration is in ../common/lidar/lidar_stages.h): this plugin's version
// keys its cached results.
#include "lidar_stages.h"
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("odometry", "0.6.0", "Wheel odometry of the platform",
                locforge::lidar::DiffDrive)

// The stages of kind odometry; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::lidar {
LOCFORGE_DECLARE_STAGE(AddDiffDrive);
}  // namespace locforge::lidar

LOCFORGE_PLUGIN("odometry", "0.7.0", "Wheel odometry of the platform",
                locforge::Exported<locforge::lidar::AddDiffDrive>)

// The stages of kind source; each stage's version keys its cached results.
// source/simulator is its own plugin (simulator/),
// the example sources source/synthetic_images and source/image_list are in
// the examples plugin (../example/plugin.cc).
#include "locforge/plugin.h"

namespace locforge::lidar {
LOCFORGE_DECLARE_STAGE(AddPcdKeyframes);
}  // namespace locforge::lidar

namespace locforge::colmap_stages {
LOCFORGE_DECLARE_STAGE(AddKaptureFolder);
}  // namespace locforge::colmap_stages

namespace locforge::velodyne {
LOCFORGE_DECLARE_STAGE(AddVelodynePcap);
}  // namespace locforge::velodyne

LOCFORGE_PLUGIN("source", "0.7.0", "Sources: kapture folders, LiDAR keyframes, Velodyne packet captures",
                locforge::Exported<locforge::lidar::AddPcdKeyframes>,
                locforge::Exported<locforge::colmap_stages::AddKaptureFolder>,
                locforge::Exported<locforge::velodyne::AddVelodynePcap>)

// The stages of kind source. source/pcd_keyframes declares no version of its own (its
// declaration is in ../common/lidar/lidar_stages.h): this plugin's version
// keys its cached results. source/simulator is its own plugin (simulator/),
// the example sources source/synthetic_images and source/image_list are in
// the examples plugin (../example/plugin.cc).
#include "lidar_stages.h"
#include "locforge/plugin.h"

namespace locforge::colmap_stages {
LOCFORGE_DECLARE_STAGE(AddKaptureFolder);
}  // namespace locforge::colmap_stages

namespace locforge::velodyne {
LOCFORGE_DECLARE_STAGE(AddVelodynePcap);
}  // namespace locforge::velodyne

LOCFORGE_PLUGIN("source", "0.6.0", "Sources: kapture folders, LiDAR keyframes, Velodyne packet captures",
                locforge::lidar::PcdKeyframes,
                locforge::Exported<locforge::colmap_stages::AddKaptureFolder>,
                locforge::Exported<locforge::velodyne::AddVelodynePcap>)

#include "stages.h"

LOCFORGE_PLUGIN("lidar", "0.3.1",
                "LiDAR ground-truth pipeline: wheel odometry, scan preprocessing, pose-graph SLAM",
                locforge::lidar::DiffDrive, locforge::lidar::Preprocess, locforge::lidar::PoseGraphSlam, locforge::lidar::LidarToLidar)

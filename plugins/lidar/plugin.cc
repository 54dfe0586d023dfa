#include "stages.h"

LOCFORGE_PLUGIN("lidar", "0.6.0",
                "LiDAR ground-truth pipeline: wheel odometry, scan preprocessing, pose-graph SLAM, keyframe import",
                locforge::lidar::DiffDrive, locforge::lidar::Preprocess, locforge::lidar::PoseGraphSlam, locforge::lidar::LidarToLidar,
                locforge::lidar::PcdKeyframes)

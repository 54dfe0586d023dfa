// The lidar and trajectory_eval plugins through the SDK's conformance kit:
// they load, their metadata is complete and bad parameters are refused.
#include <gtest/gtest.h>

#include "locforge/testkit.h"

namespace {

TEST(LidarPlugin, Conforms) {
  const auto report = locforge::testkit::CheckPlugin(LOCFORGE_LIDAR_PLUGIN_FILE);
  EXPECT_TRUE(report.ok()) << report.ToString();
}

TEST(TrajectoryEvalPlugin, Conforms) {
  const auto report = locforge::testkit::CheckPlugin(LOCFORGE_EVAL_PLUGIN_FILE);
  EXPECT_TRUE(report.ok()) << report.ToString();
}

}  // namespace

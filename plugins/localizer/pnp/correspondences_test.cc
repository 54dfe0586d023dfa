// CorrespondenceSet: a 3D point matched from several map images counts once,
// so a look-alike mapped from many images cannot outvote the true place.
#include "correspondences.h"

#include <gtest/gtest.h>

#include <random>

#include "test_scene.h"

namespace locforge::localization {
namespace {

using localization::testing::PointsInView;

TEST(CorrespondenceSet, EachKeypointAndPointOnce) {
  CorrespondenceSet set;
  const Eigen::Vector2d x(0.1, 0.2);
  const Eigen::Vector3d p(1, 2, 3);
  EXPECT_TRUE(set.Add(0, 7, 42, x, p));
  EXPECT_FALSE(set.Add(0, 7, 42, x, p));  // the same point through a second map image
  EXPECT_TRUE(set.Add(0, 7, 43, x, p));   // another 3D point for that keypoint
  EXPECT_TRUE(set.Add(0, 8, 42, x, p));   // another keypoint on that point
  EXPECT_TRUE(set.Add(1, 7, 42, x, p));   // another camera of the rig
  EXPECT_EQ(set.correspondences().size(), 4u);
  EXPECT_EQ(set.correspondences()[3].camera, 1);
}

// 120 correspondences of the true place, each seen from one map image, and 60 of
// a look-alike 3 m away, each matched through 3 map images. Counted per map
// image the look-alike wins RANSAC (180 against 120); counted once it loses.
TEST(CorrespondenceSet, LookAlikeSeenFromManyMapImagesDoesNotOutvoteTheTruePlace) {
  std::mt19937 rng(5);
  const Pose truth(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY())),
                   Eigen::Vector3d(0.2, -0.1, 0.5));
  const Pose look_alike(truth.q, truth.t + Eigen::Vector3d(3.0, 0, 0));
  std::normal_distribution<double> noise(0, 0.5 / 500);  // 0.5 px at f = 500
  CorrespondenceSet set;
  std::vector<Correspondence> per_map_image;
  int64_t id = 0;
  for (const auto& p : PointsInView(truth, 120, rng, 3.0)) {
    const Eigen::Vector2d x = (truth * p).hnormalized() + Eigen::Vector2d(noise(rng), noise(rng));
    set.Add(0, id, id, x, p);
    per_map_image.push_back({x, p, 0});
    ++id;
  }
  for (const auto& p : PointsInView(look_alike, 60, rng, 3.0)) {
    const Eigen::Vector2d x = (look_alike * p).hnormalized() + Eigen::Vector2d(noise(rng), noise(rng));
    for (int map_image = 0; map_image < 3; ++map_image) {
      set.Add(0, id, id, x, p);
      per_map_image.push_back({x, p, 0});
    }
    ++id;
  }
  ASSERT_EQ(set.correspondences().size(), 180u);
  ASSERT_EQ(per_map_image.size(), 300u);
  RigCamera camera;
  camera.focal = 500;
  RansacOptions ransac;
  const AbsolutePoseResult once = EstimateAbsolutePose(set.correspondences(), {camera}, ransac);
  ASSERT_TRUE(once.success) << once.failure;
  EXPECT_LT((once.rig_from_world.Center() - truth.Center()).norm(), 0.05);
  EXPECT_EQ(once.num_inliers, 120);
  // The property the set exists for: with the duplicates, the look-alike wins.
  const AbsolutePoseResult duplicated = EstimateAbsolutePose(per_map_image, {camera}, ransac);
  ASSERT_TRUE(duplicated.success) << duplicated.failure;
  EXPECT_GT((duplicated.rig_from_world.Center() - truth.Center()).norm(), 2.5);
}

}  // namespace
}  // namespace locforge::localization

// The parts of the outer loop on a small scene with a known answer: one
// camera on a rig moving along x, three points seen by every image.
#include "outer_loop.h"

#include <gtest/gtest.h>

#include <cmath>

namespace locforge::sfm_gt {
namespace {

constexpr Timestamp kSecond = 1000000;  // microseconds, the default unit

struct Scene {
  State state;
  colmap::Reconstruction model;
  std::map<colmap::CameraId, std::string> sensor_of{{1, "cam"}};
};

// The camera looks along the rig's x axis (camera z = rig x); the rig is at
// x = t (m) at time t (s), for t in [0, 2]; images at t = 0.5 and 1.0, and one
// at t = 10 outside the recorded trajectory.
Scene MakeScene() {
  Scene s;
  State::CameraState cam;
  cam.camera = Camera::FromModelName("PINHOLE", 640, 480, {500, 500, 320, 240});
  const Eigen::Matrix3d R_cam_rig = (Eigen::Matrix3d() << 0, -1, 0, 0, 0, -1, 1, 0, 0).finished();
  cam.T_cam_rig = Pose(Eigen::Quaterniond(R_cam_rig), Eigen::Vector3d::Zero());
  s.state.cameras["cam"] = cam;
  RigSequence seq;
  for (int i = 0; i <= 20; ++i) {
    seq.timestamps.push_back(i * kSecond / 10);
    seq.T_world_rig.push_back(Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1 * i, 0, 0)));
  }
  s.state.sequences.push_back(seq);
  const std::vector<Eigen::Vector3d> points = {{5, 0.5, 0.2}, {6, -0.4, -0.3}, {7, 0.1, 0.6}};
  s.model.cameras.push_back({1, cam.camera});
  const std::vector<std::pair<std::string, Timestamp>> images = {
      {"a.jpg", kSecond / 2}, {"b.jpg", kSecond}, {"late.jpg", 10 * kSecond}};
  for (size_t i = 0; i < images.size(); ++i) {
    const Pose T_world_rig(Eigen::Quaterniond::Identity(),
                           Eigen::Vector3d(static_cast<double>(images[i].second) / kSecond, 0, 0));
    const Pose T_cam_world = *cam.T_cam_rig * T_world_rig.Inverse();
    s.state.images[images[i].first] = {"cam", images[i].second, T_cam_world};
    colmap::ModelImage im;
    im.image_id = static_cast<colmap::ImageId>(i + 1);
    im.camera_id = 1;
    im.name = images[i].first;
    im.SetCameraFromWorld(T_cam_world);
    for (const auto& p : points) {
      colmap::Point2D p2;
      p2.xy = cam.camera.Project(T_cam_world * p);
      im.points2d.push_back(p2);
    }
    s.model.images.push_back(im);
  }
  for (size_t k = 0; k < points.size(); ++k) {
    colmap::ModelPoint3D p;
    p.point3d_id = k + 1;
    p.xyz = points[k];
    for (size_t i = 0; i < images.size(); ++i)
      p.track.push_back({static_cast<colmap::ImageId>(i + 1), static_cast<colmap::Point2DIdx>(k)});
    s.model.points3d.push_back(p);
  }
  return s;
}

TEST(OuterLoop, MeanReprojectionUsesTheStateNotTheModel) {
  Scene s = MakeScene();
  // late.jpg's camera (at x = 10 m) has the points (x = 5..7 m) behind it:
  // its 3 observations do not count.
  ReprojStats r = MeanReprojection(s.model, s.state, s.sensor_of);
  EXPECT_EQ(r.observations, 6);
  EXPECT_LT(r.mean_px, 1e-9);
  // One observation 5 px off: the mean over 6 is 5/6 px.
  s.model.images[0].points2d[1].xy += Eigen::Vector2d(3, 4);
  r = MeanReprojection(s.model, s.state, s.sensor_of);
  EXPECT_NEAR(r.mean_px, 5.0 / 6.0, 1e-9);
  // The model's own poses do not count: moving them changes nothing.
  s.model.images[1].SetCameraFromWorld(Pose());
  EXPECT_NEAR(MeanReprojection(s.model, s.state, s.sensor_of).mean_px, 5.0 / 6.0, 1e-9);
}

TEST(OuterLoop, BuildProblemKeepsImagesInsideTheirSequence) {
  const Scene s = MakeScene();
  OuterLoopOptions o;
  ProblemIndex index;
  const sfm::BAProblem p = BuildProblem(s.model, s.state, s.sensor_of, o, 0, &index);
  EXPECT_EQ(p.Validate(), "");
  ASSERT_EQ(p.trajectories.size(), 1u);
  EXPECT_EQ(p.trajectories[0].times_s.size(), 21u);
  EXPECT_DOUBLE_EQ(p.trajectories[0].times_s.back(), 2.0);
  ASSERT_EQ(p.sensors.size(), 1u);
  EXPECT_TRUE(p.sensors[0].calibrate_intrinsics);
  EXPECT_TRUE(p.sensors[0].calibrate_rotation);
  // The rig-from-camera extrinsic is the inverse of the camera-from-rig one.
  EXPECT_LT((p.sensors[0].T_body_camera.Matrix() - s.state.cameras.at("cam").T_cam_rig->Inverse().Matrix())
                .cwiseAbs()
                .maxCoeff(),
            1e-12);
  // late.jpg (t = 10 s) lies beyond the sequence's end + 0.5 s.
  EXPECT_EQ(index.skipped_images, 1);
  ASSERT_EQ(index.image_names, (std::vector<std::string>{"a.jpg", "b.jpg"}));
  EXPECT_DOUBLE_EQ(p.images[1].time_s, 1.0);
  EXPECT_EQ(p.points.size(), 3u);
  EXPECT_EQ(p.observations.size(), 6u);
  // A problem of the bundle adjuster's own options: calibration off for all sensors.
  o.ba.calibrate_intrinsics = false;
  EXPECT_FALSE(BuildProblem(s.model, s.state, s.sensor_of, o, 0, &index).sensors[0].calibrate_intrinsics);
}

TEST(OuterLoop, PoseChangeIsTheRmsOverImages) {
  const Scene s = MakeScene();
  State moved = s.state;
  // a.jpg 3 cm along its camera's x, b.jpg turned 0.4 deg: RMS over 3 images.
  auto& a = moved.images.at("a.jpg").T_cam_world;
  a = Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.03, 0, 0)) * a;
  auto& b = moved.images.at("b.jpg").T_cam_world;
  b = Pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.4 * M_PI / 180, Eigen::Vector3d::UnitY())),
           Eigen::Vector3d::Zero()) *
      b;
  const PoseChange c = Compare(s.state, moved);
  EXPECT_NEAR(c.position_m, std::sqrt(0.03 * 0.03 / 3), 1e-9);
  EXPECT_NEAR(c.rotation_deg, std::sqrt(0.4 * 0.4 / 3), 1e-6);
}

TEST(OuterLoop, ConvergedOnlyAtTheLastThresholdBelowEveryTolerance) {
  OuterLoopOptions o;
  const PoseChange small{0.0001, 0.001}, large{0.01, 0.001};
  EXPECT_TRUE(Converged(o, true, small, 0.50, 0.51));
  EXPECT_FALSE(Converged(o, false, small, 0.50, 0.51));  // thresholds still to lower
  EXPECT_FALSE(Converged(o, true, small, -1, 0.51));     // first round
  EXPECT_FALSE(Converged(o, true, large, 0.50, 0.51));   // poses still moving
  EXPECT_FALSE(Converged(o, true, small, 0.50, 0.60));   // reprojection still changing
}

TEST(OuterLoop, CheckCallsTheBundleAdjustersOwnCheck) {
  OuterLoopOptions o;
  std::string why;
  EXPECT_TRUE(o.Check(&why)) << why;
  // The sequence alignment needs the trajectory prior it corrects.
  o.ba.trajectory_prior_sigma_translation_m = 0;
  EXPECT_FALSE(o.Check(&why));
  EXPECT_NE(why.find("align_trajectories needs the trajectory prior"), std::string::npos) << why;
  o.ba.align_trajectories = false;
  EXPECT_TRUE(o.Check(&why)) << why;
  o.filter_max_reproj_error = {};
  EXPECT_FALSE(o.Check(&why));
}

}  // namespace
}  // namespace locforge::sfm_gt

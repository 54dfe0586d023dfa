// The blocked bundle adjustment against the whole one on the synthetic scene
// of spline_ba_test.cc (2 sequences over the same space, 3 cameras): the
// same solution within 1 mm / 0.01 deg.
#include "blocked_ba.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "locforge/units.h"
#include "synthetic.h"

namespace locforge::sfm {
namespace {

const SyntheticScene& Scene() {
  static const SyntheticScene scene = MakeSyntheticScene(TestSceneOptions());
  return scene;
}

// The synthetic scene's settings with the sequences aligned (the stage's
// default) and the calibration held: what a blocked pass sees after the
// calibrated rounds.
SplineBAOptions CalibrationHeld() {
  SplineBAOptions options = SyntheticSceneBAOptions();
  options.num_threads = 2;
  options.align_trajectories = true;
  options.calibrate_intrinsics = options.calibrate_rotations = options.estimate_time_offsets = false;
  return options;
}

// Largest camera centre (m) and rotation (deg) difference.
std::pair<double, double> Difference(const BAProblem& a, const BAProblem& b) {
  double dm = 0, ddeg = 0;
  for (size_t i = 0; i < a.images.size(); ++i) {
    dm = std::max(dm, (a.images[i].T_world_camera.t - b.images[i].T_world_camera.t).norm());
    ddeg = std::max(ddeg, a.images[i].T_world_camera.q.angularDistance(b.images[i].T_world_camera.q) / kDeg);
  }
  return {dm, ddeg};
}

// The starting state with the true calibration (intrinsics, camera
// rotations, clock offsets).
BAProblem CalibratedStart() {
  BAProblem p = Scene().initial;
  p.sensors = Scene().truth.sensors;
  return p;
}

TEST(BlockedBA, TwoSequencesSameAsWhole) {
  const SplineBAOptions options = CalibrationHeld();
  BAProblem whole = CalibratedStart();
  const SplineBAResult w = RunSplineBA(options, &whole);
  ASSERT_TRUE(w.usable) << w.message;
  BAProblem blocked = CalibratedStart();
  BlockedBAOptions two;
  two.blocks = 2;
  int progress_lines = 0;
  two.progress = [&](const std::string&) { ++progress_lines; };
  const BlockedBAResult r = RunBlockedSplineBA(options, two, &blocked);
  ASSERT_TRUE(r.usable) << r.message;
  const auto [dm, ddeg] = Difference(whole, blocked);
  const SceneErrors ew = CompareToTruth(whole, Scene().truth), eb = CompareToTruth(blocked, Scene().truth);
  std::printf("  %s in %.1f s (whole %.1f s); blocks of %d + %d images, %d + %d observations and %d + %d point "
              "summaries (whole: %d observations); "
              "blocked vs whole: %.4f mm / %.5f deg; against the truth: whole %.3f cm / %.4f deg, blocked %.3f cm / "
              "%.4f deg\n",
              r.message.c_str(), r.seconds, w.seconds, r.block_images[0], r.block_images[1], r.block_observations[0],
              r.block_observations[1], r.block_summaries[0], r.block_summaries[1], w.num_observations, 1000 * dm, ddeg, 100 * ew.position_rms_m,
              ew.rotation_rms_deg, 100 * eb.position_rms_m, eb.rotation_rms_deg);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(progress_lines, r.passes);  // one line per pass
  ASSERT_EQ(r.block_images.size(), 2u);
  EXPECT_EQ(r.block_images[0] + r.block_images[1], static_cast<int>(whole.images.size()));
  // A block holds its own observations only (its memory), the neighbours' as one summary per point.
  EXPECT_EQ(r.block_observations[0] + r.block_observations[1], static_cast<int>(whole.observations.size()));
  EXPECT_LT(dm, 0.001);
  EXPECT_LT(ddeg, 0.01);
}

TEST(BlockedBA, DealsTrajectoriesByImageCount) {
  BAProblem p;
  p.trajectories.resize(3);
  for (int t = 0; t < 3; ++t)
    for (int n = 0; n < (t == 0 ? 5 : 3); ++n) p.images.push_back({t, 0, 0.0, Pose(), ""});
  p.images.push_back({-1, 0, 0.0, Pose(), ""});
  const std::vector<int> b = AssignBlocks(p, 2);
  // 5 images to block 0, then 3 to block 1, then 3 to block 1 (3 < 5); none to block 0.
  EXPECT_EQ(b[0], 0);
  EXPECT_EQ(b[5], 1);
  EXPECT_EQ(b[8], 1);
  EXPECT_EQ(b.back(), 0);
}

TEST(BlockedBA, RefusesWhatItCannotBlock) {
  BAProblem p = Scene().initial;
  SplineBAOptions plain = CalibrationHeld();
  plain.use_spline_prior = false;
  const BlockedBAResult r = RunBlockedSplineBA(plain, {}, &p);
  EXPECT_FALSE(r.usable);
  EXPECT_NE(r.message.find("spline prior"), std::string::npos) << r.message;
  SplineBAOptions calibrating = CalibrationHeld();
  calibrating.calibrate_intrinsics = true;
  EXPECT_NE(RunBlockedSplineBA(calibrating, {}, &p).message.find("calibration"), std::string::npos);
  BlockedBAOptions bad;
  bad.blocks = 0;
  EXPECT_NE(RunBlockedSplineBA(CalibrationHeld(), bad, &p).message.find("blocks"), std::string::npos);
  EXPECT_EQ(Difference(p, Scene().initial).first, 0.0);  // nothing changed
}

}  // namespace
}  // namespace locforge::sfm

#include "join_consensus.h"

#include <gtest/gtest.h>

#include <random>

namespace locforge::lidar {
namespace {

Pose Yaw(double deg, const Eigen::Vector3d& t) {
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(deg * M_PI / 180, Eigen::Vector3d::UnitZ())), t);
}

// A candidate at b keyframe `b` (position p_b in B's frame) whose loop
// measured the frame transform `T` up to noise (sigma_t m, sigma_r deg).
JoinCandidate Candidate(int a, int b, const Eigen::Vector3d& p_b, const Pose& T, std::mt19937& rng,
                        double sigma_t = 0.02, double sigma_r = 0.2, double overlap = 0.7) {
  std::normal_distribution<double> n(0, 1);
  Vector6d xi;
  xi << n(rng) * sigma_r * M_PI / 180, n(rng) * sigma_r * M_PI / 180, n(rng) * sigma_r * M_PI / 180,
      n(rng) * sigma_t, n(rng) * sigma_t, n(rng) * sigma_t;
  JoinCandidate c;
  c.a = a;
  c.b = b;
  c.p_b = p_b;
  c.T_A_B = ExpSE3(xi) * T;
  c.overlap = overlap;
  return c;
}

TEST(JoinConsensus, VerifiedClusterWinsOverWrongHeadingsAndOutliers) {
  std::mt19937 rng(3);
  const Pose truth = Yaw(-179, Eigen::Vector3d(0.3, -0.2, 0));
  std::vector<JoinCandidate> c;
  // 6 correct loops at distinct places along B (up to 15 m from its
  // origin): 2 seeds near the start, 4 found where the hypothesis predicted.
  for (int i = 0; i < 6; ++i) {
    c.push_back(Candidate(10 + i, 100 + 5 * i, Eigen::Vector3d(3.0 * i, 1.0 * (i % 2), 0), truth, rng));
    c.back().predicted = i >= 2;
  }
  // A wrong heading at a symmetric start (a square room): 7 seed loops at 6
  // distinct b keyframes agreeing with each other (more than the correct
  // cluster's 6, better overlaps), and 1 of its predicted loops found.
  const Pose wrong = Yaw(-89, Eigen::Vector3d(0.5, 0.1, 0));
  for (int i = 0; i < 7; ++i)
    c.push_back(Candidate(1, 200 + std::min(i, 5), Eigen::Vector3d(0.2 * i, 0, 0), wrong, rng, 0.02, 0.2, 0.9));
  c.push_back(Candidate(3, 210, Eigen::Vector3d(4.0, 0.2, 0), wrong, rng));
  c.back().predicted = true;
  // Two isolated predicted outliers: 30 deg off, and 1.5 m off.
  c.push_back(Candidate(4, 103, Eigen::Vector3d(2, 0, 0), Yaw(-149, truth.t), rng));
  c.push_back(Candidate(5, 104, Eigen::Vector3d(4, 0, 0), Yaw(-179, truth.t + Eigen::Vector3d(1.5, 0, 0)), rng));
  c[c.size() - 1].predicted = c[c.size() - 2].predicted = true;

  const JoinConsensus r = FindJoinConsensus(c, JoinConsensusOptions{});
  ASSERT_TRUE(r.found);
  EXPECT_EQ(r.support, 6);
  EXPECT_EQ(r.verified, 4);
  EXPECT_EQ(r.rival_verified, 1);  // the wrong heading's cluster
  EXPECT_EQ(r.inliers, (std::vector<int>{0, 1, 2, 3, 4, 5}));
  EXPECT_EQ(r.outliers.size(), 10u);
  EXPECT_EQ(r.supports[6], 7);  // the wrong cluster had the most support
  EXPECT_LT(RotationAngleDeg(r.T_A_B.q, truth.q), 1.0);
  EXPECT_LT((r.T_A_B * Eigen::Vector3d(10, 0, 0) - truth * Eigen::Vector3d(10, 0, 0)).norm(), 0.3);
}

TEST(JoinConsensus, OnePlaceSeedsOnlyOrAnAmbiguousRivalIsNoJoin) {
  std::mt19937 rng(5);
  const Pose truth = Yaw(68, Eigen::Vector3d(0.1, 0.4, 0));
  JoinConsensusOptions o;
  // Four agreeing predicted loops, but all from one b keyframe: one place only.
  std::vector<JoinCandidate> c;
  for (int i = 0; i < 4; ++i) {
    c.push_back(Candidate(i, 7, Eigen::Vector3d(1, 0, 0), truth, rng));
    c.back().predicted = true;
  }
  JoinConsensus r = FindJoinConsensus(c, o);
  EXPECT_FALSE(r.found);
  EXPECT_EQ(r.support, 1);
  EXPECT_EQ(r.verified, 1);
  // Five agreeing seed loops at distinct places, none verified.
  c.clear();
  for (int i = 0; i < 5; ++i) c.push_back(Candidate(i, 10 + i, Eigen::Vector3d(i, 0, 0), truth, rng));
  r = FindJoinConsensus(c, o);
  EXPECT_FALSE(r.found);
  EXPECT_EQ(r.support, 5);
  EXPECT_EQ(r.verified, 0);
  // Three verified places agree with the truth, three with a 90 deg wrong
  // heading: ambiguous.
  c.clear();
  for (int i = 0; i < 3; ++i) c.push_back(Candidate(i, 10 + i, Eigen::Vector3d(i, 0, 0), truth, rng));
  for (int i = 0; i < 3; ++i) c.push_back(Candidate(i, 20 + i, Eigen::Vector3d(0, i, 0), Yaw(158, truth.t), rng));
  for (auto& x : c) x.predicted = true;
  r = FindJoinConsensus(c, o);
  EXPECT_FALSE(r.found);
  EXPECT_EQ(r.verified, 3);
  EXPECT_EQ(r.rival_verified, 3);
  // A fourth and fifth place for the truth: 5 vs 3 is still too close at
  // ratio 0.5; with 6 it is a join.
  for (int i = 3; i < 6; ++i) {
    c.push_back(Candidate(i, 10 + i, Eigen::Vector3d(i, 0, 0), truth, rng));
    c.back().predicted = true;
    r = FindJoinConsensus(c, o);
    EXPECT_EQ(r.found, i == 5) << i;
  }
  EXPECT_EQ(r.verified, 6);
  EXPECT_LT(RotationAngleDeg(r.T_A_B.q, truth.q), 1.0);
  // No candidates: no centre, no join.
  r = FindJoinConsensus({}, o);
  EXPECT_FALSE(r.found);
  EXPECT_EQ(r.centre, -1);
}

TEST(JoinConsensus, AgreementIsMeasuredAtTheKeyframesNotAtTheOrigin) {
  JoinConsensusOptions o;
  o.max_translation = 0.5;
  o.max_rotation_deg = 3;
  JoinCandidate x, y;
  x.T_A_B = Yaw(0, Eigen::Vector3d::Zero());
  y.T_A_B = Yaw(2, Eigen::Vector3d::Zero());  // same origin, 2 deg apart
  x.p_b = Eigen::Vector3d(1, 0, 0);
  y.p_b = Eigen::Vector3d(2, 0, 0);
  EXPECT_TRUE(HypothesesAgree(x, y, o));  // 2 deg at 2 m: 7 cm
  y.p_b = Eigen::Vector3d(20, 0, 0);
  EXPECT_FALSE(HypothesesAgree(x, y, o));  // 2 deg at 20 m: 70 cm
  y.p_b = Eigen::Vector3d(2, 0, 0);
  y.T_A_B = Yaw(3.5, Eigen::Vector3d::Zero());
  EXPECT_FALSE(HypothesesAgree(x, y, o));  // rotation above 3 deg
  EXPECT_TRUE(o.Check());
  o.max_rival_ratio = 2;
  std::string why;
  EXPECT_FALSE(o.Check(&why));
  EXPECT_NE(why.find("max_rival_ratio"), std::string::npos);
}

}  // namespace
}  // namespace locforge::lidar

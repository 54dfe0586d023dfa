#include "pose_graph.h"

#include <gtest/gtest.h>

#include <iostream>
#include <random>

#include "locforge/error.h"

#include "testing.h"

namespace locforge::lidar {
namespace {

TEST(PoseGraph, ParkingGarageOptimisesBelowItsInitialCost) {
  LOCFORGE_SHARED_PATH_OR_SKIP(path, "data/posegraph/parking-garage.g2o");
  PoseGraph graph = ReadG2o(path);
  EXPECT_EQ(graph.nodes.size(), 1661u);
  EXPECT_EQ(graph.edges.size(), 6275u);
  const double initial = PoseGraphCost(graph);
  const PoseGraphSummary s = Optimize(PoseGraphOptions{}, &graph);
  EXPECT_NEAR(s.initial_cost, initial, 1e-6 * initial);
  EXPECT_LT(s.final_cost, 0.5 * initial) << s.report;
  EXPECT_NEAR(PoseGraphCost(graph), s.final_cost, 1e-6 * initial + 1e-9);
  std::cout << "parking-garage cost " << initial << " -> " << s.final_cost << " (" << s.report << ")\n";
}

// A square loop with drifted odometry and one loop edge: the optimiser puts
// the nodes back within millimetres; a wrong loop edge under Cauchy barely
// moves them.
TEST(PoseGraph, LoopClosureRemovesDriftAndCauchyResistsAnOutlier) {
  std::vector<Pose> truth;
  Pose p;
  for (int i = 0; i < 40; ++i) {
    truth.push_back(p);
    const bool corner = i % 10 == 9;
    p = p * Pose(Eigen::Quaterniond(Eigen::AngleAxisd(corner ? M_PI / 2 : 0, Eigen::Vector3d::UnitZ())),
                 Eigen::Vector3d(corner ? 0 : 1, 0, 0));
  }
  std::mt19937 rng(1);
  std::normal_distribution<double> n(0, 0.002);
  auto build = [&](bool outlier) {
    PoseGraph g;
    g.nodes[0] = truth[0];
    for (int i = 1; i < 40; ++i) {
      const Pose rel = truth[i - 1].Inverse() * truth[i];
      const Pose noisy = rel * ExpSE3((Vector6d() << n(rng), n(rng), n(rng) + 0.005, n(rng), n(rng), n(rng)).finished());
      g.nodes[i] = g.nodes[i - 1] * noisy;
      g.edges.push_back({i - 1, i, noisy, Matrix6d::Identity() * 1e4});
    }
    PoseGraphEdge loop{39, 0, truth[39].Inverse() * truth[0], Matrix6d::Identity() * 1e4, RobustLoss::kCauchy, 1.0, true};
    g.edges.push_back(loop);
    if (outlier) {
      PoseGraphEdge bad{30, 5, Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(3, 0, 0)),
                        Matrix6d::Identity() * 1e4, RobustLoss::kCauchy, 1.0, true};
      g.edges.push_back(bad);
    }
    g.fixed = {0};
    return g;
  };
  double worst_without_outlier = 0;
  for (bool outlier : {false, true}) {
    rng.seed(1);
    PoseGraph g = build(outlier);
    double drift_before = 0;
    for (int i = 0; i < 40; ++i) drift_before = std::max(drift_before, (g.nodes[i].t - truth[i].t).norm());
    Optimize(PoseGraphOptions{}, &g);
    double worst = 0;
    for (int i = 0; i < 40; ++i) worst = std::max(worst, (g.nodes[i].t - truth[i].t).norm());
    EXPECT_GT(drift_before, 0.5);
    if (!outlier) worst_without_outlier = worst;
    EXPECT_LT(worst, outlier ? worst_without_outlier + 0.05 : 0.3 * drift_before) << "outlier " << outlier;
  }
}

// The registration's information (left perturbation, (w, v) order) moved into
// the edge residual's coordinates keeps the quadratic form: for small xi,
// xi^T H xi == r^T Omega r with r the graph residual of T_ab' = Exp(xi) T_ab.
TEST(PoseGraph, RegistrationInformationMatchesTheEdgeResidualNumerically) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0, 1);
  for (int trial = 0; trial < 5; ++trial) {
    const Pose T_ab(ExpSO3(Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.5), Eigen::Vector3d(n(rng), n(rng), n(rng)));
    Matrix6d A;
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c) A(r, c) = n(rng);
    const Matrix6d H = A * A.transpose() + Matrix6d::Identity();
    const Matrix6d omega = RegistrationInformationToEdge(H, T_ab);
    for (int k = 0; k < 5; ++k) {
      Vector6d xi;
      for (int i = 0; i < 6; ++i) xi(i) = n(rng) * 1e-5;
      const Eigen::Quaterniond dq = ExpSO3(xi.head<3>());
      const Pose perturbed(dq * T_ab.q, dq * T_ab.t + xi.tail<3>());  // (Exp(w), v) T_ab
      Vector6d r;
      r.head<3>() = perturbed.t - T_ab.t;
      r.tail<3>() = 2 * (T_ab.q.conjugate() * perturbed.q).vec();
      const double expected = xi.dot(H * xi);
      EXPECT_NEAR(r.dot(omega * r), expected, 1e-4 * expected) << "trial " << trial;
    }
  }
}

// Rescaling keeps the shape: the best direction gets the given sigma, a
// direction 100x weaker in the Hessian stays weaker (down to the floor).
TEST(PoseGraph, NormalizeInformationKeepsTheShapeAndFloors) {
  Vector6d d;
  d << 1e6, 1e6, 1e2, 4e5, 4e5, 4e5;  // z translation 100x weaker (1e4 in information)
  Matrix6d out;
  ASSERT_TRUE(NormalizeInformation(d.asDiagonal(), 0.01, 0.002, 10, &out));
  EXPECT_NEAR(out(0, 0), 1e4 + 1e2, 1e-6);                   // 1/0.01^2 + floor 1/(10*0.01)^2
  EXPECT_NEAR(out(2, 2), 1e4 * 1e-4 + 1e2, 1e-6);            // weak direction: its share + floor
  EXPECT_NEAR(out(3, 3), 1 / (0.002 * 0.002) * 1.01, 1e-3);  // rotation block likewise
  Matrix6d bad = Matrix6d::Zero();
  EXPECT_FALSE(NormalizeInformation(bad, 0.01, 0.002, 10, &out));
}

TEST(PoseGraph, G2oRoundTripAndErrors) {
  const auto dir = testing::MakeTempDir("g2o");
  PoseGraph g;
  g.nodes[3] = Pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())), Eigen::Vector3d(1, 2, 3));
  g.nodes[7] = Pose();
  Matrix6d info = Matrix6d::Identity();
  info(0, 4) = info(4, 0) = 0.25;
  g.edges.push_back({3, 7, g.nodes[3].Inverse(), info});
  g.fixed = {3};
  WriteG2o(dir / "g.g2o", g);
  const PoseGraph r = ReadG2o(dir / "g.g2o");
  ASSERT_EQ(r.nodes.size(), 2u);
  EXPECT_LT((r.nodes.at(3).t - g.nodes[3].t).norm(), 1e-12);
  EXPECT_NEAR(r.edges[0].information(4, 0), 0.25, 1e-15);
  EXPECT_EQ(r.fixed, std::vector<int>{3});
  WriteFileAtomic(dir / "bad.g2o", "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nEDGE_SE3:QUAT 0 1 0 0\n");
  try {
    ReadG2o(dir / "bad.g2o");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.g2o:2"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace locforge::lidar

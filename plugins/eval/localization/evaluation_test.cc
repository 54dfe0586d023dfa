#include "evaluation.h"

#include <gtest/gtest.h>

#include <cmath>

#include "locforge/error.h"

namespace locforge::evaluation {
namespace {

TEST(Errors, HandComputed) {
  // GT camera at the origin looking down z; estimate: centre at (3, 4, 0),
  // rotated 90 deg about z.
  const Pose gt = Pose::Identity();
  const Eigen::Quaterniond r(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  const Pose est(r, -(r * Eigen::Vector3d(3, 4, 0)));
  const QueryError e = ComputeError(gt, est);
  ASSERT_TRUE(e.localized);
  EXPECT_NEAR(e.position_m, 5.0, 1e-12);
  EXPECT_NEAR(e.rotation_deg, 90.0, 1e-9);
  EXPECT_FALSE(ComputeError(gt, std::nullopt).localized);
}

TEST(Recall, InclusiveBoundsAndFailures) {
  std::vector<QueryError> errors(5);
  errors[0] = {"a", "", "", "", true, 0.1, 1.0};   // exactly on the bound: counted
  errors[1] = {"b", "", "", "", true, 0.1, 1.01};  // angle over
  errors[2] = {"c", "", "", "", true, 0.25, 0.5};
  errors[3] = {"d", "", "", "", true, 0.05, 0.1};
  errors[4] = {"e", "", "", "", false, 0, 0};      // unlocalized: failure, not 0 error
  EXPECT_DOUBLE_EQ(Recall(errors, {0.1, 1.0}), 2.0 / 5);
  EXPECT_DOUBLE_EQ(Recall(errors, {0.25, 2.0}), 4.0 / 5);
  EXPECT_DOUBLE_EQ(Recall(errors, {1e9, 1e9}), 4.0 / 5);
  EXPECT_DOUBLE_EQ(Recall({}, {1, 1}), 0.0);
  EXPECT_DOUBLE_EQ(MedianPosition(errors), 0.1);
  EXPECT_EQ(Percent(2.0 / 3), "66.7");
}

TEST(Tables, Writers) {
  Table t{{"method", "a_b", "x"}, {{"sift+vlad", "1, 2", "q\"uote"}, {"m|n", "50%", "3"}}};
  EXPECT_EQ(ToMarkdown(t),
            "| method | a_b | x |\n|---|---|---|\n| sift+vlad | 1, 2 | q\"uote |\n"
            "| m\\|n | 50% | 3 |\n");
  EXPECT_EQ(ToCsv(t), "method,a_b,x\nsift+vlad,\"1, 2\",\"q\"\"uote\"\nm|n,50%,3\n");
  const Table back = FromCsv(ToCsv(t), "t.csv");
  EXPECT_EQ(back.header, t.header);
  EXPECT_EQ(back.rows, t.rows);
  EXPECT_EQ(ToLatex(t),
            "\\begin{tabular}{lcc}\n\\hline\nmethod & a\\_b & x \\\\\n\\hline\n"
            "sift+vlad & 1, 2 & q\"uote \\\\\nm|n & 50\\% & 3 \\\\\n\\hline\n\\end{tabular}\n");
  EXPECT_THROW(FromCsv("a,b\n1\n", "bad.csv"), InputError);
}

TEST(Curve, MatchesRecallAtEachThresholdPair) {
  // Errors (m, deg): (0.05, 0.2) counts from p = 0.05 on (angle 0.5 >= 0.2);
  // (0.05, 2.95) only from p = 0.3 (angle 3); (0.5, 1) from p = 0.5; one failure.
  std::vector<QueryError> e(4);
  e[0] = {"a", "", "", "", true, 0.05, 0.2};
  e[1] = {"b", "", "", "", true, 0.05, 2.95};
  e[2] = {"c", "", "", "", true, 0.5, 1.0};
  e[3] = {"d", "", "", "", false, 0, 0};
  const plot::Series s = RecallCurve(e, "m", 1.0, 10, 100);
  ASSERT_EQ(s.x.size(), 101u);
  EXPECT_EQ(s.label, "m");
  EXPECT_DOUBLE_EQ(s.y[0], 0);
  EXPECT_DOUBLE_EQ(s.y[4], 0);     // p = 0.04
  EXPECT_DOUBLE_EQ(s.y[5], 25);    // p = 0.05
  EXPECT_DOUBLE_EQ(s.y[29], 25);
  EXPECT_DOUBLE_EQ(s.y[30], 50);   // p = 0.3, angle 3
  EXPECT_DOUBLE_EQ(s.y[50], 75);   // p = 0.5
  EXPECT_DOUBLE_EQ(s.y[100], 75);  // the failure never counts
  for (size_t i = 0; i < s.x.size(); ++i)
    EXPECT_DOUBLE_EQ(s.y[i], 100 * Recall(e, {s.x[i], 10 * s.x[i]}));
  // Geometric thresholds: 50 per decade from 1 mm to 1 m.
  const plot::Series g = RecallCurve(e, "m", 1.0, 10, 150, 3);
  ASSERT_EQ(g.x.size(), 151u);
  EXPECT_NEAR(g.x[0], 0.001, 1e-15);
  EXPECT_NEAR(g.x[50], 0.01, 1e-15);
  EXPECT_DOUBLE_EQ(g.x[150], 1.0);
  for (size_t i = 0; i < g.x.size(); ++i) {
    EXPECT_DOUBLE_EQ(g.y[i], 100 * Recall(e, {g.x[i], 10 * g.x[i]}));
    if (i > 0) EXPECT_NEAR(g.x[i] / g.x[i - 1], std::pow(10.0, 1.0 / 50), 1e-12);
  }
  const plot::Figure f = RecallFigure({s}, "t", 1.0);
  EXPECT_EQ(f.series.size(), 1u);
  EXPECT_TRUE(f.x_log);
  EXPECT_DOUBLE_EQ(f.x_min, 0.001);
  EXPECT_DOUBLE_EQ(f.x_max, 1.0);
  EXPECT_DOUBLE_EQ(f.y_max, 100);
  const auto png = plot::RenderPng(f);
  ASSERT_GT(png.size(), 8u);
  EXPECT_EQ(std::string(png.begin(), png.begin() + 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_NE(plot::RenderSvg(f).find("<svg"), std::string::npos);
}

}  // namespace
}  // namespace locforge::evaluation

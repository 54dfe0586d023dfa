#include "evaluation.h"

#include <gtest/gtest.h>

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

TEST(Svg, ContainsSeries) {
  const std::string svg = SvgLinePlot({{"a<b", {0, 1}, {0, 100}}}, "x", "y", 1, 100);
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_NE(svg.find("a&lt;b"), std::string::npos);
  EXPECT_NE(svg.find("<polyline"), std::string::npos);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
}

}  // namespace
}  // namespace locforge::evaluation

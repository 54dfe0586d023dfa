// The crowd sweep's tables and plot on hand-made sets with known recalls.
#include "crowd_sweep.h"

#include <gtest/gtest.h>

#include "locforge/error.h"
#include "testing_queries.h"

namespace locforge::analysis {
namespace {

using evaluation::QueryError;

QueryError Query(const std::string& image, bool localized, double position_m, double rotation_deg) {
  return testing::Q(image, localized, position_m, rotation_deg);
}

// Set 0 (no crowd): 4 queries at 0-2 % crowdedness, method A localizes all
// within 5 cm, B three of four. Set 1 (dense): 4 queries at 10-50 %, A
// localizes 2 within 5 cm and 1 at 0.5 m, B 1.
std::vector<SweepSet> Sets() {
  std::vector<SweepSet> sets(2);
  sets[0].setting = 0;
  sets[1].setting = 16;
  const double crowd[2][4] = {{0, 1, 2, 1}, {10, 30, 50, 22}};
  for (int s = 0; s < 2; ++s)
    for (int i = 0; i < 4; ++i)
      sets[s].content.push_back(Classify("q" + std::to_string(i), 30, crowd[s][i], {20, 20}));
  sets[0].methods = {{"A", {Query("q0", true, 0.05, 0.5), Query("q1", true, 0.05, 0.5), Query("q2", true, 0.05, 0.5),
                            Query("q3", true, 0.05, 0.5)}},
                     {"B", {Query("q0", true, 0.05, 0.5), Query("q1", true, 0.05, 0.5), Query("q2", true, 0.05, 0.5),
                            Query("q3", false, 0, 0)}}};
  sets[1].methods = {{"A", {Query("q0", true, 0.05, 0.5), Query("q1", true, 0.05, 0.5), Query("q2", true, 0.5, 3),
                            Query("q3", false, 0, 0)}},
                     {"B", {Query("q0", true, 0.05, 0.5), Query("q1", false, 0, 0), Query("q2", false, 0, 0),
                            Query("q3", false, 0, 0)}}};
  return sets;
}

const std::vector<evaluation::Threshold> kPaper = {{0.1, 1}, {0.25, 2}, {1, 5}};

TEST(CrowdSweep, RowPerSetWithMeanCrowdednessAndRecalls) {
  const auto sets = Sets();
  ASSERT_NO_THROW(CheckSweep(sets));
  EXPECT_DOUBLE_EQ(MeanCrowdedness(sets[0]), 1.0);
  EXPECT_DOUBLE_EQ(MeanCrowdedness(sets[1]), 28.0);
  const evaluation::Table t = SweepTable(sets, kPaper);
  ASSERT_EQ(t.rows.size(), 2u);
  EXPECT_EQ(t.header.back(), "B");
  EXPECT_EQ(t.rows[0], (std::vector<std::string>{"0", "4", "1.0", "0.0", "100.0 / 100.0 / 100.0", "75.0 / 75.0 / 75.0"}));
  EXPECT_EQ(t.rows[1], (std::vector<std::string>{"16", "4", "28.0", "75.0", "50.0 / 50.0 / 75.0", "25.0 / 25.0 / 25.0"}));
}

TEST(CrowdSweep, QueriesBinnedByTheirOwnCrowdedness) {
  const evaluation::Table t = BinnedTable(Sets(), {0, 5, 20}, kPaper);
  ASSERT_EQ(t.rows.size(), 3u);
  EXPECT_EQ(t.rows[0][0], "[0, 5)");
  EXPECT_EQ(t.rows[0][1], "4");  // set 0's four
  EXPECT_EQ(t.rows[1][1], "1");  // 10 %
  EXPECT_EQ(t.rows[2][0], ">= 20");
  EXPECT_EQ(t.rows[2][1], "3");  // 30, 50, 22 %
  EXPECT_EQ(t.rows[2][2], "33.3 / 33.3 / 66.7");  // A: q1 ok, q2 at 0.5 m, q3 failed
  EXPECT_EQ(t.rows[1][3], "100.0 / 100.0 / 100.0");  // B on q0 of set 1
}

TEST(CrowdSweep, FigureHasOnePointPerSetPerMethod) {
  const plot::Figure f = SweepFigure(Sets(), kPaper[1]);
  ASSERT_EQ(f.series.size(), 2u);
  EXPECT_EQ(f.series[0].x, (std::vector<double>{1.0, 28.0}));
  EXPECT_EQ(f.series[0].y, (std::vector<double>{100.0, 50.0}));
  EXPECT_EQ(f.series[1].y, (std::vector<double>{75.0, 25.0}));
}

TEST(CrowdSweep, PartialJoinsAndMismatchedMethodsAreRefused) {
  auto sets = Sets();
  sets[1].methods[1].method = "C";
  EXPECT_THROW(CheckSweep(sets), InputError);
  sets = Sets();
  sets[1].content.pop_back();  // q3 of set 1 has no content
  EXPECT_THROW(CheckSweep(sets), InputError);
  sets = Sets();
  sets[0].content[2].crowdedness_percent = -1;  // no mask
  EXPECT_THROW(CheckSweep(sets), InputError);
  sets = Sets();
  sets[1].methods.pop_back();
  EXPECT_THROW(CheckSweep(sets), InputError);
}

}  // namespace
}  // namespace locforge::analysis

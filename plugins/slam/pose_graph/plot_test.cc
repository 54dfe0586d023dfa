// The top-down figure of the pose-graph stage: what it draws and what its
// legend says, on two hand-made sequences with known loop edges.
#include "plot.h"

#include <gtest/gtest.h>

namespace locforge::lidar {
namespace {

TEST(TopDown, DashedBeforeSolidAfterLoopsAndALegendForEach) {
  PlotSequence a{"seq_a", {0, 1, 2}, {{0, 0}, {1, 0}, {2, 0}}};
  PlotSequence b{"seq_b", {3, 4}, {{0, 1}, {2, 1}}};
  PlotSequence a_before = a, b_before = b;
  for (auto& p : a_before.xy) p.y() += 0.2;
  const plot::Figure f = TopDownFigure({a_before, b_before}, {a, b}, {{0, 3}, {2, 4}, {1, 99}});
  EXPECT_TRUE(f.equal_aspect);
  // Per sequence one dashed unlabelled "before" line (drawn first, under the
  // rest) and one solid labelled "after" line in the same colour; then the
  // two legend-only keys.
  ASSERT_EQ(f.series.size(), 6u);
  for (size_t s = 0; s < 2; ++s) {
    const plot::Series& before = f.series[s];
    const plot::Series& after = f.series[2 + s];
    EXPECT_TRUE(before.dashed);
    EXPECT_EQ(before.label, "");
    EXPECT_EQ(before.color.substr(0, 7), plot::PaletteColor(s));
    EXPECT_FALSE(after.dashed);
    EXPECT_EQ(after.color, plot::PaletteColor(s));
  }
  EXPECT_EQ(f.series[0].y, (std::vector<double>{0.2, 0.2, 0.2}));
  EXPECT_EQ(f.series[2].label, "seq_a");
  EXPECT_EQ(f.series[3].label, "seq_b");
  EXPECT_EQ(f.series[4].label, "before optimisation");
  EXPECT_TRUE(f.series[4].dashed);
  EXPECT_TRUE(f.series[4].x.empty());
  EXPECT_EQ(f.series[5].label, "loop closures");
  EXPECT_EQ(f.series[5].color, f.segments.at(0).color);
  // Two loop edges between known nodes (the one naming node 99 is dropped),
  // drawn between the optimised positions.
  ASSERT_EQ(f.segments.size(), 2u);
  EXPECT_DOUBLE_EQ(f.segments[1].x0, 2.0);
  EXPECT_DOUBLE_EQ(f.segments[1].y1, 1.0);
  // It renders (SVG and PNG), legend and all.
  EXPECT_GT(plot::RenderPng(f).size(), 5000u);
  EXPECT_NE(plot::RenderSvg(f).find("<title>"), std::string::npos);
}

}  // namespace
}  // namespace locforge::lidar

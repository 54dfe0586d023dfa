// Shared by the SVG and PNG renderers: ticks, colours, data extents.
#ifndef LOCFORGE_SDK_SRC_PLOT_LAYOUT_H_
#define LOCFORGE_SDK_SRC_PLOT_LAYOUT_H_

#include <array>
#include <string>
#include <vector>

#include "locforge/plot.h"

namespace locforge::plot::internal {

// Margins around the plot area, in pixels.
constexpr int kMarginLeft = 80;
constexpr int kMarginRight = 20;
constexpr int kMarginTop = 40;
constexpr int kMarginBottom = 56;

// "Nice" tick values (1, 2, 5 x 10^k) covering [lo, hi], about `target` of them.
std::vector<double> Ticks(double lo, double hi, int target);
// A tick label: as few digits as the tick step needs.
std::string TickLabel(double value, double step);

std::array<uint8_t, 3> ParseColor(const std::string& hex);
// The colour a series is drawn in (its own, or the palette's).
std::string SeriesColor(const Figure& figure, size_t index);

// Top-left corner of a w x h legend box: the corner of the plot area that
// covers the fewest data points (as matplotlib's loc="best").
Eigen::Vector2d LegendOrigin(const Figure& figure, const Frame& frame, double w, double h);

}  // namespace locforge::plot::internal

#endif  // LOCFORGE_SDK_SRC_PLOT_LAYOUT_H_

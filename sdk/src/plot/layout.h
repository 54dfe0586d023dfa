// Where everything goes, shared by the drawing and ComputeFrame: ticks,
// margins fitted to the text, the legend's entries and place, colours.
#ifndef LOCFORGE_SDK_SRC_PLOT_LAYOUT_H_
#define LOCFORGE_SDK_SRC_PLOT_LAYOUT_H_

#include <functional>
#include <string>
#include <vector>

#include "locforge/plot.h"

namespace locforge::plot::internal {

// Sizes in pixels (at 96 dpi: 13 px is a 10 pt font, as in papers' figures
// printed at column width).
constexpr double kTickFont = 13;
constexpr double kLabelFont = 14;
constexpr double kTitleFont = 16;
constexpr double kLegendFont = 13;
constexpr double kTickLength = 5;
constexpr double kPad = 8;  // between text blocks and the figure's edge

// "Nice" tick values (1, 2, 5 x 10^k) covering [lo, hi], about `target` of them.
std::vector<double> Ticks(double lo, double hi, int target);
// The nice step of Ticks(lo, hi, target).
double TickStep(double lo, double hi, int target);
// Multiples of `step` inside [lo, hi].
std::vector<double> TicksWithStep(double lo, double hi, double step);
// A tick label: as few digits as the tick step needs.
std::string TickLabel(double value, double step);
// The same for display: a real minus sign (U+2212) instead of '-'.
std::string DisplayTickLabel(double value, double step);
// Ticks of a log axis over [lo, hi] (0 < lo < hi): `major` (labelled) at
// 1 x 10^k, also at 2 and 5 x 10^k when `gap(major)` (the pixels the labels
// need between neighbours) allows, every n-th decade when it must; `minor`
// at the other m x 10^k (m = 1..9) where a decade is wide enough for them.
void LogTicks(double lo, double hi, double length_px, const std::function<double(const std::vector<double>&)>& gap,
              std::vector<double>* major, std::vector<double>* minor);
// A log tick's label: "0.01", "0.5", "20", "1e-06".
std::string LogTickLabel(double value);

struct Rgba {
  double r = 0, g = 0, b = 0, a = 1;
};
// "#rrggbb" or "#rrggbbaa"; throws locforge::Error naming `what` otherwise.
Rgba ParseColor(const std::string& hex, const std::string& what);
// The colour a series is drawn in (its own, or the palette's).
std::string SeriesColor(const Figure& figure, size_t index);

// Valid UTF-8 without control characters (Cairo refuses invalid UTF-8 and
// stops drawing; XML refuses control characters): bad bytes become U+FFFD.
std::string CleanText(const std::string& text);

// Drawing sizes of the data, pixels.
constexpr double kLineWidth = 2;
constexpr double kDotRadius = 3.5;

// One row of the legend: the sample drawn as the series is.
struct LegendEntry {
  std::string label;
  Rgba color;
  bool line = true;
  bool dashed = false;
  bool markers = false;
};

struct Layout {
  Frame frame;
  std::vector<double> x_ticks, y_ticks;            // labelled, with grid lines
  std::vector<std::string> x_labels, y_labels;      // their labels
  std::vector<double> x_minor, y_minor;            // log axes: short unlabelled ticks
  double x_step = 1, y_step = 1;                    // linear axes: the tick step
  double title_size = kTitleFont;  // smaller when a long title would not fit
  std::vector<LegendEntry> legend;
  double legend_x = 0, legend_y = 0, legend_w = 0, legend_h = 0;  // box, pixels
  double legend_row = 0;  // row height
};
// Throws locforge::Error on a bad figure (size, colours, x/y lengths).
Layout ComputeLayout(const Figure& figure);

// Clips the segment a-b to the rectangle [x0, x1] x [y0, y1] (Liang-Barsky);
// false when nothing is left. Keeps coordinates handed to Cairo small (its
// fixed-point numbers overflow far outside the picture).
bool ClipSegment(Eigen::Vector2d* a, Eigen::Vector2d* b, double x0, double y0, double x1, double y1);

// Legend geometry (shared by the layout and the drawing).
constexpr double kLegendPad = 8;
constexpr double kLegendSample = 30;  // length of the line sample

}  // namespace locforge::plot::internal

#endif  // LOCFORGE_SDK_SRC_PLOT_LAYOUT_H_

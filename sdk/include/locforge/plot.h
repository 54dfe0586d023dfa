// Plots a person would rather look at than read: line charts, trajectories
// and edges. One drawing gives both formats: SVG (vector, scales, for papers
// and HTML reports) and PNG (for viewers, CI artifacts, READMEs). The library
// draws with Cairo and writes text in DejaVu Sans (Debian's fonts-dejavu-core;
// fontconfig's sans-serif when it is missing); neither shows in this header.
//
//   plot::Figure f;
//   f.title = "Localization recall";
//   f.x_label = "position error (m)";
//   f.series.push_back({"SIFT", xs, ys});
//   plot::WriteFigure(f, dir + "/curve.png");   // or .svg
//
// What the figure shows: a light grid at "nice" ticks (1, 2, 5 x 10^k), tick
// labels, axis labels, a title, and a legend of the labelled series, placed
// in the corner or edge of the plot area that hides the least data. Output
// is deterministic: the same figure gives the same bytes (on the same Cairo,
// libpng and font), so caches and tests stay stable.
#ifndef LOCFORGE_PLOT_H_
#define LOCFORGE_PLOT_H_

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace locforge::plot {

// Colours are "#rrggbb" or "#rrggbbaa" (aa = opacity, ff opaque); anything
// else makes the renderers throw locforge::Error naming the series.
struct Series {
  std::string label;       // legend entry; empty = not in the legend
  std::vector<double> x;   // same length as y; non-finite points break the line
  std::vector<double> y;
  std::string color;       // empty = PaletteColor(index of the series)
  bool markers = false;    // a dot at every point
  bool dashed = false;     // e.g. a trajectory before optimisation
  bool line = true;        // false: markers only (a scatter)
};
// A series with a label and no points is a legend entry only: one grey dashed
// "before optimisation" entry for several dashed series, or the key of the
// segments. Lines are 2 pixels wide, dots 7 pixels across.

// A free segment in data coordinates (e.g. a loop-closure edge), drawn under
// the series, 1 pixel wide; not in the legend (add a series without points).
struct Segment {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  std::string color = "#d55e00";
};

struct Figure {
  std::string title;
  std::string x_label;
  std::string y_label;
  std::vector<Series> series;
  std::vector<Segment> segments;
  bool equal_aspect = false;  // one metre is as long on both axes (maps)
  int width = 800;            // pixels (PNG) / CSS pixels (SVG), 100..10000
  int height = 600;
  // Axis ranges; NaN = from the data with a 3 % margin.
  double x_min = std::numeric_limits<double>::quiet_NaN();
  double x_max = std::numeric_limits<double>::quiet_NaN();
  double y_min = std::numeric_limits<double>::quiet_NaN();
  double y_max = std::numeric_limits<double>::quiet_NaN();
  // Logarithmic axes, for values spread over decades (error thresholds from
  // 1 mm to 1 m): ticks at 1 (2, 5) x 10^k; points <= 0 are not drawn. Not
  // with equal_aspect.
  bool x_log = false;
  bool y_log = false;
};

// Where the data lands in the picture: the plot area in pixels (y down) and
// the data ranges it shows. Exposed so tests can check the drawing. The
// margins fit the tick labels, axis labels and title in the figure's font.
struct Frame {
  double x_min = 0, x_max = 1, y_min = 0, y_max = 1;
  int left = 0, top = 0, right = 1, bottom = 1;
  bool x_log = false, y_log = false;
  // Non-finite for a point that cannot be drawn (<= 0 on a log axis).
  Eigen::Vector2d ToPixel(double x, double y) const;
};
Frame ComputeFrame(const Figure& figure);

// The colour series i gets when it names none: the Okabe-Ito palette (told
// apart with every common colour-vision deficiency), 8 colours, repeating.
std::string PaletteColor(size_t i);

// The SVG document (UTF-8). Text is drawn as glyph outlines, so it looks the
// same everywhere; the figure's title is also its <title>. Element ids carry
// a prefix hashed from the drawing, so several figures can be inlined in one
// HTML page.
std::string RenderSvg(const Figure& figure);
// An 8-bit RGB PNG file's bytes, width x height pixels.
std::vector<uint8_t> RenderPng(const Figure& figure);
// Writes ".svg" or ".png" by the path's extension, atomically; throws
// locforge::Error on another extension, a bad figure or an I/O failure.
void WriteFigure(const Figure& figure, const std::string& path);

}  // namespace locforge::plot

#endif  // LOCFORGE_PLOT_H_

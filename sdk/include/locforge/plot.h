// Plots a person would rather look at than read: line charts, trajectories
// and edges, written as SVG (vector, for papers) and PNG (for viewers, CI
// artifacts, READMEs). No third-party plotting library: the PNG rasteriser
// draws lines, markers and a built-in 5x7 bitmap font, and zlib compresses.
//
//   plot::Figure f;
//   f.title = "Localization recall";
//   f.series.push_back({"SIFT", xs, ys});
//   plot::WriteFigure(f, dir + "/curve.png");   // or .svg
#ifndef LOCFORGE_PLOT_H_
#define LOCFORGE_PLOT_H_

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace locforge::plot {

struct Series {
  std::string label;       // legend entry; empty = not in the legend
  std::vector<double> x;   // same length as y; non-finite points break the line
  std::vector<double> y;
  std::string color;       // "#rrggbb"; empty = next colour of the palette
  bool markers = false;    // a dot at every point
  bool dashed = false;
  bool line = true;        // false: markers only (a scatter)
};

// A free segment in data coordinates (e.g. a loop-closure edge).
struct Segment {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  std::string color = "#d62728";
};

struct Figure {
  std::string title;
  std::string x_label;
  std::string y_label;
  std::vector<Series> series;
  std::vector<Segment> segments;
  bool equal_aspect = false;  // one metre is as long on both axes (maps)
  int width = 800;            // pixels (PNG) / user units (SVG)
  int height = 600;
  // Axis ranges; NaN = from the data with a 3 % margin.
  double x_min = std::numeric_limits<double>::quiet_NaN();
  double x_max = std::numeric_limits<double>::quiet_NaN();
  double y_min = std::numeric_limits<double>::quiet_NaN();
  double y_max = std::numeric_limits<double>::quiet_NaN();
};

// Where the data lands in the picture: the plot area in pixels (y down) and
// the data ranges it shows. Exposed so tests can check the drawing.
struct Frame {
  double x_min = 0, x_max = 1, y_min = 0, y_max = 1;
  int left = 0, top = 0, right = 1, bottom = 1;
  Eigen::Vector2d ToPixel(double x, double y) const;
};
Frame ComputeFrame(const Figure& figure);

// The colour series i gets when it names none.
std::string PaletteColor(size_t i);

std::string RenderSvg(const Figure& figure);
// An 8-bit RGB PNG file's bytes.
std::vector<uint8_t> RenderPng(const Figure& figure);
// Writes ".svg" or ".png" by the path's extension, atomically; throws
// locforge::Error on another extension or an I/O failure.
void WriteFigure(const Figure& figure, const std::string& path);

}  // namespace locforge::plot

#endif  // LOCFORGE_PLOT_H_

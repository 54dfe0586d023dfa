// SVG renderer and WriteFigure.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "layout.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/plot.h"

namespace locforge::plot {
namespace {

std::string Escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '&': out += "&amp;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string Num(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.2f", v);
  return buffer;
}

}  // namespace

std::string RenderSvg(const Figure& figure) {
  const Frame f = ComputeFrame(figure);
  std::ostringstream svg;
  svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << figure.width << "\" height=\""
      << figure.height << "\" viewBox=\"0 0 " << figure.width << ' ' << figure.height
      << "\" font-family=\"sans-serif\" font-size=\"13\">\n";
  svg << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";

  // Grid and tick labels.
  const std::vector<double> xt = internal::Ticks(f.x_min, f.x_max, 8);
  const std::vector<double> yt = internal::Ticks(f.y_min, f.y_max, 6);
  for (double x : xt) {
    const double u = f.ToPixel(x, f.y_min).x();
    svg << "<line x1=\"" << Num(u) << "\" y1=\"" << f.top << "\" x2=\"" << Num(u) << "\" y2=\""
        << f.bottom << "\" stroke=\"#e0e0e0\"/>\n";
    svg << "<text x=\"" << Num(u) << "\" y=\"" << f.bottom + 18 << "\" text-anchor=\"middle\">"
        << internal::TickLabel(x, xt.size() > 1 ? xt[1] - xt[0] : 1.0) << "</text>\n";
  }
  for (double y : yt) {
    const double v = f.ToPixel(f.x_min, y).y();
    svg << "<line x1=\"" << f.left << "\" y1=\"" << Num(v) << "\" x2=\"" << f.right << "\" y2=\""
        << Num(v) << "\" stroke=\"#e0e0e0\"/>\n";
    svg << "<text x=\"" << f.left - 6 << "\" y=\"" << Num(v + 4) << "\" text-anchor=\"end\">"
        << internal::TickLabel(y, yt.size() > 1 ? yt[1] - yt[0] : 1.0) << "</text>\n";
  }
  svg << "<rect x=\"" << f.left << "\" y=\"" << f.top << "\" width=\"" << f.right - f.left
      << "\" height=\"" << f.bottom - f.top << "\" fill=\"none\" stroke=\"black\"/>\n";

  // Data, clipped to the plot area.
  svg << "<clipPath id=\"area\"><rect x=\"" << f.left << "\" y=\"" << f.top << "\" width=\""
      << f.right - f.left << "\" height=\"" << f.bottom - f.top << "\"/></clipPath>\n";
  svg << "<g clip-path=\"url(#area)\">\n";
  for (const Segment& s : figure.segments) {
    const Eigen::Vector2d a = f.ToPixel(s.x0, s.y0), b = f.ToPixel(s.x1, s.y1);
    svg << "<line x1=\"" << Num(a.x()) << "\" y1=\"" << Num(a.y()) << "\" x2=\"" << Num(b.x())
        << "\" y2=\"" << Num(b.y()) << "\" stroke=\"" << s.color << "\" stroke-width=\"1\"/>\n";
  }
  for (size_t i = 0; i < figure.series.size(); ++i) {
    const Series& s = figure.series[i];
    const std::string color = internal::SeriesColor(figure, i);
    const size_t n = std::min(s.x.size(), s.y.size());
    if (s.line) {
      std::string points;
      auto flush = [&] {
        if (!points.empty()) {
          svg << "<polyline fill=\"none\" stroke=\"" << color << "\" stroke-width=\"2\""
              << (s.dashed ? " stroke-dasharray=\"6,4\"" : "") << " points=\"" << points
              << "\"/>\n";
        }
        points.clear();
      };
      for (size_t k = 0; k < n; ++k) {
        if (!std::isfinite(s.x[k]) || !std::isfinite(s.y[k])) {
          flush();
          continue;
        }
        const Eigen::Vector2d p = f.ToPixel(s.x[k], s.y[k]);
        points += Num(p.x()) + "," + Num(p.y()) + " ";
      }
      flush();
    }
    if (s.markers || !s.line) {
      for (size_t k = 0; k < n; ++k) {
        if (!std::isfinite(s.x[k]) || !std::isfinite(s.y[k])) continue;
        const Eigen::Vector2d p = f.ToPixel(s.x[k], s.y[k]);
        svg << "<circle cx=\"" << Num(p.x()) << "\" cy=\"" << Num(p.y()) << "\" r=\"3\" fill=\""
            << color << "\"/>\n";
      }
    }
  }
  svg << "</g>\n";

  // Legend: a white box in the top-right corner of the plot area (text
  // width estimated at 7.5 units per character of the 13-unit font).
  size_t rows = 0, widest = 0;
  for (const Series& s : figure.series) {
    if (!s.label.empty()) ++rows, widest = std::max(widest, s.label.size());
  }
  if (rows > 0) {
    const double w = 7.5 * widest + 44, h = 6 + 18.0 * rows;
    const Eigen::Vector2d origin = internal::LegendOrigin(figure, f, w, h);
    const double x0 = origin.x(), y0 = origin.y();
    svg << "<rect x=\"" << Num(x0) << "\" y=\"" << Num(y0) << "\" width=\"" << Num(w)
        << "\" height=\"" << Num(h) << "\" fill=\"white\" stroke=\"#a0a0a0\"/>\n";
    int row = 0;
    for (size_t i = 0; i < figure.series.size(); ++i) {
      if (figure.series[i].label.empty()) continue;
      const double y = y0 + 18 + 18 * row++;
      const std::string color = internal::SeriesColor(figure, i);
      svg << "<line x1=\"" << Num(x0 + 6) << "\" y1=\"" << Num(y - 4) << "\" x2=\"" << Num(x0 + 30)
          << "\" y2=\"" << Num(y - 4) << "\" stroke=\"" << color << "\" stroke-width=\"3\""
          << (figure.series[i].dashed ? " stroke-dasharray=\"6,4\"" : "") << "/>\n";
      svg << "<text x=\"" << Num(x0 + 38) << "\" y=\"" << Num(y) << "\">"
          << Escape(figure.series[i].label) << "</text>\n";
    }
  }

  svg << "<text x=\"" << (f.left + f.right) / 2 << "\" y=\"24\" text-anchor=\"middle\" "
      << "font-size=\"16\">" << Escape(figure.title) << "</text>\n";
  svg << "<text x=\"" << (f.left + f.right) / 2 << "\" y=\"" << figure.height - 12
      << "\" text-anchor=\"middle\">" << Escape(figure.x_label) << "</text>\n";
  svg << "<text transform=\"translate(18," << (f.top + f.bottom) / 2
      << ") rotate(-90)\" text-anchor=\"middle\">" << Escape(figure.y_label) << "</text>\n";
  svg << "</svg>\n";
  return svg.str();
}

void WriteFigure(const Figure& figure, const std::string& path) {
  const std::string extension = std::filesystem::path(path).extension().string();
  if (extension == ".svg") {
    WriteFileAtomic(path, RenderSvg(figure));
  } else if (extension == ".png") {
    const std::vector<uint8_t> png = RenderPng(figure);
    WriteFileAtomic(path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  } else {
    throw Error("cannot write figure '" + path + "': the extension must be .svg or .png");
  }
}

}  // namespace locforge::plot

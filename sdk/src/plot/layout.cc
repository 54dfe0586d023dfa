#include "layout.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>

namespace locforge::plot {
namespace internal {

std::vector<double> Ticks(double lo, double hi, int target) {
  std::vector<double> ticks;
  if (!(hi > lo) || target < 1) return ticks;
  const double raw = (hi - lo) / target;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  double step = magnitude;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    step = m * magnitude;
    if (step >= raw) break;
  }
  // Multiples of the step (not a running sum, which drifts: 0.6000000001).
  for (double k = std::ceil(lo / step - 1e-9); k * step <= hi + 1e-9 * step; k += 1) {
    ticks.push_back(k == 0 ? 0.0 : k * step);
  }
  return ticks;
}

std::string TickLabel(double value, double step) {
  const int decimals = std::clamp(static_cast<int>(-std::floor(std::log10(step) + 1e-9)), 0, 6);
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value);
  return buffer;
}

std::array<uint8_t, 3> ParseColor(const std::string& hex) {
  std::array<uint8_t, 3> rgb{0, 0, 0};
  if (hex.size() != 7 || hex[0] != '#') return rgb;
  for (int i = 0; i < 3; ++i) {
    rgb[i] = static_cast<uint8_t>(std::stoi(hex.substr(1 + 2 * i, 2), nullptr, 16));
  }
  return rgb;
}

std::string SeriesColor(const Figure& figure, size_t index) {
  const std::string& own = figure.series[index].color;
  return own.empty() ? PaletteColor(index) : own;
}

Eigen::Vector2d LegendOrigin(const Figure& figure, const Frame& frame, double w, double h) {
  const Eigen::Vector2d candidates[] = {{frame.right - 4 - w, frame.top + 4.0},
                                        {frame.left + 4.0, frame.top + 4.0},
                                        {frame.right - 4 - w, frame.bottom - 4 - h},
                                        {frame.left + 4.0, frame.bottom - 4 - h}};
  Eigen::Vector2d best = candidates[0];
  size_t fewest = SIZE_MAX;
  for (const Eigen::Vector2d& c : candidates) {
    size_t covered = 0;
    for (const Series& s : figure.series) {
      for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
        if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
        const Eigen::Vector2d p = frame.ToPixel(s.x[i], s.y[i]);
        covered += p.x() >= c.x() && p.x() <= c.x() + w && p.y() >= c.y() && p.y() <= c.y() + h;
      }
    }
    if (covered < fewest) fewest = covered, best = c;
  }
  return best;
}

}  // namespace internal

std::string PaletteColor(size_t i) {
  // Matplotlib's "tab10": distinguishable, also in greyscale print.
  static const char* kPalette[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                                   "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};
  return kPalette[i % 10];
}

Eigen::Vector2d Frame::ToPixel(double x, double y) const {
  const double u = left + (x - x_min) / (x_max - x_min) * (right - left);
  const double v = bottom - (y - y_min) / (y_max - y_min) * (bottom - top);
  return {u, v};
}

Frame ComputeFrame(const Figure& figure) {
  Frame frame;
  frame.left = internal::kMarginLeft;
  frame.top = internal::kMarginTop;
  frame.right = std::max(frame.left + 10, figure.width - internal::kMarginRight);
  frame.bottom = std::max(frame.top + 10, figure.height - internal::kMarginBottom);

  double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  auto extend = [&](double x, double y) {
    if (!std::isfinite(x) || !std::isfinite(y)) return;
    x0 = std::min(x0, x), x1 = std::max(x1, x);
    y0 = std::min(y0, y), y1 = std::max(y1, y);
  };
  for (const Series& s : figure.series) {
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) extend(s.x[i], s.y[i]);
  }
  for (const Segment& s : figure.segments) extend(s.x0, s.y0), extend(s.x1, s.y1);
  if (!std::isfinite(x0)) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  if (x1 - x0 < 1e-12) x0 -= 0.5, x1 += 0.5;
  if (y1 - y0 < 1e-12) y0 -= 0.5, y1 += 0.5;
  const double mx = 0.03 * (x1 - x0), my = 0.03 * (y1 - y0);
  frame.x_min = std::isnan(figure.x_min) ? x0 - mx : figure.x_min;
  frame.x_max = std::isnan(figure.x_max) ? x1 + mx : figure.x_max;
  frame.y_min = std::isnan(figure.y_min) ? y0 - my : figure.y_min;
  frame.y_max = std::isnan(figure.y_max) ? y1 + my : figure.y_max;
  if (!(frame.x_max > frame.x_min)) frame.x_max = frame.x_min + 1;
  if (!(frame.y_max > frame.y_min)) frame.y_max = frame.y_min + 1;

  if (figure.equal_aspect) {
    // Grow the smaller range so that one data unit has the same length on
    // both axes, centred on the data.
    const double sx = (frame.right - frame.left) / (frame.x_max - frame.x_min);
    const double sy = (frame.bottom - frame.top) / (frame.y_max - frame.y_min);
    if (sx > sy) {
      const double half = 0.5 * (frame.right - frame.left) / sy;
      const double c = 0.5 * (frame.x_min + frame.x_max);
      frame.x_min = c - half, frame.x_max = c + half;
    } else {
      const double half = 0.5 * (frame.bottom - frame.top) / sx;
      const double c = 0.5 * (frame.y_min + frame.y_max);
      frame.y_min = c - half, frame.y_max = c + half;
    }
  }
  return frame;
}

}  // namespace locforge::plot

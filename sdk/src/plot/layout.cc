#include "layout.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>

#include "font.h"
#include "locforge/error.h"

namespace locforge::plot {
namespace internal {
namespace {

int HexDigit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

struct Extents {
  double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  void Add(double x, double y) {
    if (!std::isfinite(x) || !std::isfinite(y)) return;
    x0 = std::min(x0, x), x1 = std::max(x1, x);
    y0 = std::min(y0, y), y1 = std::max(y1, y);
  }
};

// The data ranges of a plot area of the frame's pixel size.
void SetRanges(const Figure& figure, const Extents& data, Frame* frame) {
  double x0 = data.x0, x1 = data.x1, y0 = data.y0, y1 = data.y1;
  if (!std::isfinite(x0)) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  if (x1 - x0 < 1e-12) x0 -= 0.5, x1 += 0.5;
  if (y1 - y0 < 1e-12) y0 -= 0.5, y1 += 0.5;
  const double mx = 0.03 * (x1 - x0), my = 0.03 * (y1 - y0);
  frame->x_min = std::isnan(figure.x_min) ? x0 - mx : figure.x_min;
  frame->x_max = std::isnan(figure.x_max) ? x1 + mx : figure.x_max;
  frame->y_min = std::isnan(figure.y_min) ? y0 - my : figure.y_min;
  frame->y_max = std::isnan(figure.y_max) ? y1 + my : figure.y_max;
  if (!(frame->x_max > frame->x_min)) frame->x_max = frame->x_min + 1;
  if (!(frame->y_max > frame->y_min)) frame->y_max = frame->y_min + 1;
  if (figure.equal_aspect) {
    // Grow the smaller range so that one data unit has the same length on
    // both axes, centred on the data.
    const double sx = (frame->right - frame->left) / (frame->x_max - frame->x_min);
    const double sy = (frame->bottom - frame->top) / (frame->y_max - frame->y_min);
    if (sx > sy) {
      const double half = 0.5 * (frame->right - frame->left) / sy;
      const double c = 0.5 * (frame->x_min + frame->x_max);
      frame->x_min = c - half, frame->x_max = c + half;
    } else {
      const double half = 0.5 * (frame->bottom - frame->top) / sx;
      const double c = 0.5 * (frame->y_min + frame->y_max);
      frame->y_min = c - half, frame->y_max = c + half;
    }
  }
}

double WidestLabel(const std::vector<double>& ticks, double step) {
  double widest = 0;
  for (double t : ticks) widest = std::max(widest, MeasureText(DisplayTickLabel(t, step), kTickFont).width);
  return widest;
}

// Ticks of both axes: about one per 100 px along x and 70 px along y, fewer
// when the x labels would touch; maps (equal aspect) use one step for both.
void SetTicks(const Figure& figure, Layout* layout) {
  const Frame& f = layout->frame;
  int x_target = std::clamp(static_cast<int>(std::lround((f.right - f.left) / 100.0)), 3, 10);
  const int y_target = std::clamp(static_cast<int>(std::lround((f.bottom - f.top) / 70.0)), 3, 10);
  layout->y_step = TickStep(f.y_min, f.y_max, y_target);
  for (;; --x_target) {
    layout->x_step = TickStep(f.x_min, f.x_max, x_target);
    if (figure.equal_aspect) layout->x_step = layout->y_step = std::max(layout->x_step, layout->y_step);
    layout->x_ticks = TicksWithStep(f.x_min, f.x_max, layout->x_step);
    const double spacing = layout->x_step / (f.x_max - f.x_min) * (f.right - f.left);
    if (x_target <= 2 || WidestLabel(layout->x_ticks, layout->x_step) + 12 <= spacing) break;
  }
  layout->y_ticks = TicksWithStep(f.y_min, f.y_max, layout->y_step);
}

// Pixel positions along every drawn line and marker, every few pixels: what
// a legend box placed there would hide.
std::vector<Eigen::Vector2d> DataSamples(const Figure& figure, const Frame& f) {
  std::vector<Eigen::Vector2d> samples;
  auto along = [&](Eigen::Vector2d a, Eigen::Vector2d b) {
    if (!ClipSegment(&a, &b, f.left, f.top, f.right, f.bottom)) return;
    const int steps = static_cast<int>(std::ceil((b - a).norm() / 3.0));
    for (int i = 0; i <= steps; ++i) samples.push_back(a + (b - a) * (steps ? double(i) / steps : 0.0));
  };
  for (const Segment& s : figure.segments) along(f.ToPixel(s.x0, s.y0), f.ToPixel(s.x1, s.y1));
  for (const Series& s : figure.series) {
    for (size_t k = 0; k < s.x.size(); ++k) {
      if (!std::isfinite(s.x[k]) || !std::isfinite(s.y[k])) continue;
      const Eigen::Vector2d p = f.ToPixel(s.x[k], s.y[k]);
      if (s.line && k + 1 < s.x.size() && std::isfinite(s.x[k + 1]) && std::isfinite(s.y[k + 1])) {
        along(p, f.ToPixel(s.x[k + 1], s.y[k + 1]));
      } else {
        along(p, p);
      }
    }
  }
  return samples;
}

// The legend's place: of the corners and edge centres of the plot area (in
// matplotlib's "best" order), the one whose box hides the fewest samples.
void PlaceLegend(const Figure& figure, Layout* layout) {
  const Frame& f = layout->frame;
  const double w = layout->legend_w, h = layout->legend_h, inset = 8;
  const double l = f.left + inset, r = f.right - inset - w, t = f.top + inset, b = f.bottom - inset - h;
  const double cx = 0.5 * (f.left + f.right - w), cy = 0.5 * (f.top + f.bottom - h);
  const Eigen::Vector2d candidates[] = {{r, t}, {l, t}, {l, b}, {r, b}, {r, cy}, {l, cy}, {cx, b}, {cx, t}};
  const std::vector<Eigen::Vector2d> samples = DataSamples(figure, f);
  size_t fewest = SIZE_MAX;
  for (const Eigen::Vector2d& c : candidates) {
    size_t hidden = 0;
    for (const Eigen::Vector2d& p : samples) {
      hidden += p.x() >= c.x() - 4 && p.x() <= c.x() + w + 4 && p.y() >= c.y() - 4 && p.y() <= c.y() + h + 4;
    }
    if (hidden < fewest) {
      fewest = hidden;
      layout->legend_x = std::round(c.x());  // whole pixels: a crisp box
      layout->legend_y = std::round(c.y());
    }
  }
}

void SetLegend(const Figure& figure, Layout* layout) {
  for (size_t i = 0; i < figure.series.size(); ++i) {
    const Series& s = figure.series[i];
    if (s.label.empty()) continue;
    layout->legend.push_back({CleanText(s.label), ParseColor(SeriesColor(figure, i), "series '" + s.label + "'"),
                              s.line, s.dashed, s.markers || !s.line});
  }
  if (layout->legend.empty()) return;
  double widest = 0;
  for (const LegendEntry& e : layout->legend) widest = std::max(widest, MeasureText(e.label, kLegendFont).width);
  layout->legend_row = std::round(1.5 * kLegendFont);
  layout->legend_w = std::ceil(2 * kLegendPad + kLegendSample + 8 + widest);
  layout->legend_h = std::ceil(kLegendPad + layout->legend.size() * layout->legend_row);
  PlaceLegend(figure, layout);
}

void Validate(const Figure& figure) {
  if (figure.width < 100 || figure.height < 100 || figure.width > 10000 || figure.height > 10000) {
    throw Error("figure size " + std::to_string(figure.width) + "x" + std::to_string(figure.height) +
                " is outside 100..10000 pixels");
  }
  for (double v : {figure.x_min, figure.x_max, figure.y_min, figure.y_max}) {
    if (!std::isnan(v) && !std::isfinite(v)) throw Error("figure '" + figure.title + "': an axis limit is infinite");
  }
  for (size_t i = 0; i < figure.series.size(); ++i) {
    const Series& s = figure.series[i];
    if (s.x.size() != s.y.size()) {
      throw Error("figure '" + figure.title + "', series '" + s.label + "': x has " + std::to_string(s.x.size()) +
                  " values, y has " + std::to_string(s.y.size()));
    }
    ParseColor(SeriesColor(figure, i), "figure '" + figure.title + "', series '" + s.label + "'");
  }
  for (const Segment& s : figure.segments) ParseColor(s.color, "figure '" + figure.title + "', a segment");
}

}  // namespace

double TickStep(double lo, double hi, int target) {
  if (!(hi > lo) || target < 1) return 1;
  const double raw = (hi - lo) / target;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  double step = magnitude;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    step = m * magnitude;
    if (step >= raw) break;
  }
  return step;
}

std::vector<double> TicksWithStep(double lo, double hi, double step) {
  std::vector<double> ticks;
  if (!(hi > lo) || !(step > 0) || (hi - lo) / step > 1000) return ticks;
  // Multiples of the step (not a running sum, which drifts: 0.6000000001).
  for (double k = std::ceil(lo / step - 1e-9); k * step <= hi + 1e-9 * step; k += 1) {
    ticks.push_back(k == 0 ? 0.0 : k * step);
  }
  return ticks;
}

std::vector<double> Ticks(double lo, double hi, int target) {
  if (!(hi > lo) || target < 1) return {};
  return TicksWithStep(lo, hi, TickStep(lo, hi, target));
}

std::string TickLabel(double value, double step) {
  const int decimals = std::clamp(static_cast<int>(-std::floor(std::log10(step) + 1e-9)), 0, 9);
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value == 0 ? 0.0 : value);
  return buffer;
}

std::string DisplayTickLabel(double value, double step) {
  std::string label = TickLabel(value, step);
  if (!label.empty() && label[0] == '-') label.replace(0, 1, "\xE2\x88\x92");
  return label;
}

Rgba ParseColor(const std::string& hex, const std::string& what) {
  bool ok = (hex.size() == 7 || hex.size() == 9) && hex[0] == '#';
  for (size_t i = 1; ok && i < hex.size(); ++i) ok = HexDigit(hex[i]) >= 0;
  if (!ok) throw Error(what + ": colour '" + hex + "' is not #rrggbb or #rrggbbaa");
  auto channel = [&](size_t at) { return (16 * HexDigit(hex[at]) + HexDigit(hex[at + 1])) / 255.0; };
  return {channel(1), channel(3), channel(5), hex.size() == 9 ? channel(7) : 1.0};
}

std::string SeriesColor(const Figure& figure, size_t index) {
  const std::string& own = figure.series[index].color;
  return own.empty() ? PaletteColor(index) : own;
}

std::string CleanText(const std::string& text) {
  std::string out;
  const auto* s = reinterpret_cast<const unsigned char*>(text.data());
  const size_t n = text.size();
  for (size_t i = 0; i < n;) {
    const unsigned char c = s[i];
    size_t length = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xe ? 3 : (c >> 3) == 0x1e ? 4 : 0;
    bool ok = length > 0 && i + length <= n;
    for (size_t k = 1; ok && k < length; ++k) ok = (s[i + k] & 0xc0) == 0x80;
    if (ok && length > 1) {
      // Overlong forms, surrogates and code points past U+10FFFF.
      uint32_t cp = c & (0xff >> (length + 1));
      for (size_t k = 1; k < length; ++k) cp = cp << 6 | (s[i + k] & 0x3f);
      const uint32_t min[] = {0, 0, 0x80, 0x800, 0x10000};
      ok = cp >= min[length] && cp <= 0x10ffff && !(cp >= 0xd800 && cp <= 0xdfff);
    }
    if (!ok) {
      out += "\xEF\xBF\xBD";
      ++i;
    } else if (length == 1 && (c < 0x20 || c == 0x7f)) {
      out += ' ';
      ++i;
    } else {
      out.append(text, i, length);
      i += length;
    }
  }
  return out;
}

bool ClipSegment(Eigen::Vector2d* a, Eigen::Vector2d* b, double x0, double y0, double x1, double y1) {
  const Eigen::Vector2d d = *b - *a;
  double t0 = 0, t1 = 1;
  const double p[] = {-d.x(), d.x(), -d.y(), d.y()};
  const double q[] = {a->x() - x0, x1 - a->x(), a->y() - y0, y1 - a->y()};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0) {
      if (q[i] < 0) return false;  // parallel to this edge and outside it
      continue;
    }
    const double t = q[i] / p[i];
    if (p[i] < 0) t0 = std::max(t0, t);
    else t1 = std::min(t1, t);
    if (t0 > t1) return false;
  }
  const Eigen::Vector2d start = *a;
  *a = start + t0 * d;
  *b = start + t1 * d;
  return std::isfinite(a->x()) && std::isfinite(a->y()) && std::isfinite(b->x()) && std::isfinite(b->y());
}

Layout ComputeLayout(const Figure& figure) {
  Validate(figure);
  Extents data;
  for (const Series& s : figure.series) {
    for (size_t i = 0; i < s.x.size(); ++i) data.Add(s.x[i], s.y[i]);
  }
  for (const Segment& s : figure.segments) data.Add(s.x0, s.y0), data.Add(s.x1, s.y1);

  Layout layout;
  const TextSize tick = MeasureText("0", kTickFont);
  const TextSize label = MeasureText("x", kLabelFont);
  const std::string title = CleanText(figure.title);
  const double title_width = title.empty() ? 0 : MeasureText(title, kTitleFont).width;
  const double room = figure.width - 2 * kPad;
  if (title_width > room) layout.title_size = std::max(8.0, kTitleFont * room / title_width);
  const TextSize title_text = MeasureText("x", layout.title_size);

  // Margins fitted to the text: the tick labels' widths depend on the ranges,
  // which (equal aspect) depend on the margins; a few rounds settle them.
  const double top = title.empty() ? std::ceil(kPad + tick.digit_height)
                                   : std::ceil(kPad + title_text.ascent + title_text.descent + 6);
  const double bottom = std::ceil(kTickLength + 4 + tick.digit_height + kPad +
                                  (figure.x_label.empty() ? 0 : 6 + label.ascent + label.descent));
  const double y_label = figure.y_label.empty() ? 0 : label.ascent + label.descent + 6;
  // Margins only grow from here, so the rounds end.
  double left = std::ceil(kPad + y_label + MeasureText("0", kTickFont).width + 4 + kTickLength);
  double right = kPad + 8;
  for (int round = 0; round < 5; ++round) {
    Frame& f = layout.frame;
    f.left = static_cast<int>(left);
    f.right = std::max(f.left + 10, figure.width - static_cast<int>(right));
    f.top = static_cast<int>(top);
    f.bottom = std::max(f.top + 10, figure.height - static_cast<int>(bottom));
    SetRanges(figure, data, &f);
    SetTicks(figure, &layout);
    const double new_left = std::ceil(kPad + y_label + WidestLabel(layout.y_ticks, layout.y_step) + 4 + kTickLength);
    double new_right = kPad + 8;
    if (!layout.x_ticks.empty()) {
      const double last = f.ToPixel(layout.x_ticks.back(), 0).x();
      const double half = 0.5 * MeasureText(DisplayTickLabel(layout.x_ticks.back(), layout.x_step), kTickFont).width;
      new_right = std::max(new_right, std::ceil(half + 4 - (f.right - last)));
    }
    if (new_left <= left && new_right <= right) break;
    left = std::max(left, new_left), right = std::max(right, new_right);
  }
  SetLegend(figure, &layout);
  return layout;
}

}  // namespace internal

std::string PaletteColor(size_t i) {
  // Okabe & Ito, "Color universal design" (2008), as recommended by Wong,
  // Nature Methods 8:441 (2011): distinct with protanopia, deuteranopia and
  // tritanopia. Ordered for contrast on white; yellow, the faintest, last.
  static const char* kPalette[] = {"#0072b2", "#e69f00", "#009e73", "#d55e00",
                                   "#cc79a7", "#56b4e9", "#000000", "#f0e442"};
  return kPalette[i % 8];
}

Eigen::Vector2d Frame::ToPixel(double x, double y) const {
  const double u = left + (x - x_min) / (x_max - x_min) * (right - left);
  const double v = bottom - (y - y_min) / (y_max - y_min) * (bottom - top);
  return {u, v};
}

Frame ComputeFrame(const Figure& figure) { return internal::ComputeLayout(figure).frame; }

}  // namespace locforge::plot

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

// The data's extent over the points that can be drawn (> 0 on log axes).
struct Extents {
  bool x_log = false, y_log = false;
  double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  void Add(double x, double y) {
    if (!std::isfinite(x) || !std::isfinite(y) || (x_log && x <= 0) || (y_log && y <= 0)) return;
    x0 = std::min(x0, x), x1 = std::max(x1, x);
    y0 = std::min(y0, y), y1 = std::max(y1, y);
  }
};

// One axis' range: the data's with a 3 % margin (of decades on a log axis),
// unless the figure fixes a limit.
void AxisRange(double lo, double hi, bool has_data, double fixed_min, double fixed_max, bool log, double* min,
               double* max) {
  const auto to = [log](double v) { return log ? std::log10(v) : v; };
  const auto from = [log](double v) { return log ? std::pow(10.0, v) : v; };
  if (!has_data) lo = log ? 1 : 0, hi = log ? 10 : 1;
  double a = to(lo), b = to(hi);
  if (b - a < 1e-12) a -= 0.5, b += 0.5;
  const double margin = 0.03 * (b - a);
  *min = std::isnan(fixed_min) ? from(a - margin) : fixed_min;
  *max = std::isnan(fixed_max) ? from(b + margin) : fixed_max;
  if (!(*max > *min)) *max = log ? *min * 10 : *min + 1;
}

// The data ranges of a plot area of the frame's pixel size.
void SetRanges(const Figure& figure, const Extents& data, Frame* frame) {
  const bool has_data = std::isfinite(data.x0);
  frame->x_log = figure.x_log;
  frame->y_log = figure.y_log;
  AxisRange(data.x0, data.x1, has_data, figure.x_min, figure.x_max, figure.x_log, &frame->x_min, &frame->x_max);
  AxisRange(data.y0, data.y1, has_data, figure.y_min, figure.y_max, figure.y_log, &frame->y_min, &frame->y_max);
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

double WidestLabel(const std::vector<std::string>& labels) {
  double widest = 0;
  for (const std::string& label : labels) widest = std::max(widest, MeasureText(label, kTickFont).width);
  return widest;
}

std::vector<std::string> LinearLabels(const std::vector<double>& ticks, double step) {
  std::vector<std::string> labels;
  for (double t : ticks) labels.push_back(DisplayTickLabel(t, step));
  return labels;
}

std::vector<std::string> LogLabels(const std::vector<double>& ticks) {
  std::vector<std::string> labels;
  for (double t : ticks) labels.push_back(LogTickLabel(t));
  return labels;
}

// Ticks of both axes: about one per 100 px along x and 70 px along y, fewer
// when the labels would touch; maps (equal aspect) use one step for both.
void SetTicks(const Figure& figure, Layout* layout) {
  const Frame& f = layout->frame;
  const double width = f.right - f.left, height = f.bottom - f.top;
  const double line = MeasureText("0", kTickFont).digit_height;
  if (figure.y_log) {
    LogTicks(f.y_min, f.y_max, height, [&](const std::vector<double>&) { return 1.8 * line; }, &layout->y_ticks,
             &layout->y_minor);
    layout->y_labels = LogLabels(layout->y_ticks);
  } else {
    const int target = std::clamp(static_cast<int>(std::lround(height / 70.0)), 3, 10);
    layout->y_step = TickStep(f.y_min, f.y_max, target);
  }
  if (figure.x_log) {
    LogTicks(f.x_min, f.x_max, width, [](const std::vector<double>& ticks) { return WidestLabel(LogLabels(ticks)) + 12; },
             &layout->x_ticks, &layout->x_minor);
    layout->x_labels = LogLabels(layout->x_ticks);
  } else {
    for (int target = std::clamp(static_cast<int>(std::lround(width / 100.0)), 3, 10);; --target) {
      layout->x_step = TickStep(f.x_min, f.x_max, target);
      if (figure.equal_aspect) layout->x_step = layout->y_step = std::max(layout->x_step, layout->y_step);
      layout->x_ticks = TicksWithStep(f.x_min, f.x_max, layout->x_step);
      layout->x_labels = LinearLabels(layout->x_ticks, layout->x_step);
      const double spacing = layout->x_step / (f.x_max - f.x_min) * width;
      if (target <= 2 || WidestLabel(layout->x_labels) + 12 <= spacing) break;
    }
  }
  if (!figure.y_log) {
    layout->y_ticks = TicksWithStep(f.y_min, f.y_max, layout->y_step);
    layout->y_labels = LinearLabels(layout->y_ticks, layout->y_step);
  }
}

// Pixel positions along every drawn line and marker, every few pixels: what
// a legend box placed there would hide.
std::vector<Eigen::Vector2d> DataSamples(const Figure& figure, const Frame& f) {
  std::vector<Eigen::Vector2d> samples;
  auto along = [&](Eigen::Vector2d a, Eigen::Vector2d b) {
    if (!a.allFinite() || !b.allFinite() || !ClipSegment(&a, &b, f.left, f.top, f.right, f.bottom)) return;
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
  if ((figure.x_log && (figure.x_min <= 0 || figure.x_max <= 0)) ||
      (figure.y_log && (figure.y_min <= 0 || figure.y_max <= 0))) {
    throw Error("figure '" + figure.title + "': a logarithmic axis needs limits > 0");
  }
  if (figure.equal_aspect && (figure.x_log || figure.y_log)) {
    throw Error("figure '" + figure.title + "': equal_aspect needs linear axes");
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

void LogTicks(double lo, double hi, double length_px, const std::function<double(const std::vector<double>&)>& gap,
              std::vector<double>* major, std::vector<double>* minor) {
  major->clear();
  minor->clear();
  if (!(lo > 0 && hi > lo && length_px > 0)) return;
  const double decades = std::log10(hi / lo), per_decade = length_px / decades;
  const int first = static_cast<int>(std::floor(std::log10(lo))), last = static_cast<int>(std::ceil(std::log10(hi)));
  if (last - first > 400) return;
  const auto inside = [&](double v) { return v >= lo * (1 - 1e-9) && v <= hi * (1 + 1e-9); };
  // Labelled choices, densest first: 1, 2, 5 x 10^k; 10^k; every n-th 10^k.
  std::vector<double> chosen;
  int stride = 1;
  for (int option = 0;; ++option) {
    const bool with_2_5 = option == 0;
    stride = std::max(1, option);
    chosen.clear();
    for (int k = first; k <= last; ++k) {
      for (double m : {1.0, 2.0, 5.0}) {
        if ((m != 1 && !with_2_5) || (m == 1 && k % stride != 0)) continue;
        const double v = m * std::pow(10.0, k);
        if (inside(v)) chosen.push_back(v);
      }
    }
    double closest = INFINITY;
    for (size_t i = 1; i < chosen.size(); ++i)
      closest = std::min(closest, std::log10(chosen[i] / chosen[i - 1]) * per_decade);
    if (chosen.size() < 2 || closest >= gap(chosen) || stride >= last - first) break;
  }
  *major = chosen;
  // Minor ticks where a decade has room for them (as matplotlib's).
  for (int k = first; k <= last; ++k) {
    for (int m = 1; m <= 9; ++m) {
      const double v = m * std::pow(10.0, k);
      if (!inside(v) || std::find(major->begin(), major->end(), v) != major->end()) continue;
      if (m == 1 || per_decade >= 60) minor->push_back(v);
    }
  }
}

std::string LogTickLabel(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%g", value);
  std::string label = buffer;
  // "1e-06" -> "1e-6", "1e+07" -> "1e7".
  const size_t e = label.find('e');
  if (e != std::string::npos) {
    std::string exponent = label.substr(e + 1);
    const bool negative = exponent[0] == '-';
    exponent.erase(0, exponent.find_first_not_of("+-0"));
    label = label.substr(0, e + 1) + (negative ? "\xE2\x88\x92" : "") + exponent;
  }
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
  data.x_log = figure.x_log, data.y_log = figure.y_log;
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
    const double new_left = std::ceil(kPad + y_label + WidestLabel(layout.y_labels) + 4 + kTickLength);
    double new_right = kPad + 8;
    if (!layout.x_ticks.empty()) {
      const double last = f.ToPixel(layout.x_ticks.back(), f.y_max).x();
      const double half = 0.5 * MeasureText(layout.x_labels.back(), kTickFont).width;
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
  // log10 of a value <= 0 is -inf or NaN: the pixel is then not finite.
  const double fx = x_log ? std::log10(x / x_min) / std::log10(x_max / x_min) : (x - x_min) / (x_max - x_min);
  const double fy = y_log ? std::log10(y / y_min) / std::log10(y_max / y_min) : (y - y_min) / (y_max - y_min);
  return {left + fx * (right - left), bottom - fy * (bottom - top)};
}

Frame ComputeFrame(const Figure& figure) { return internal::ComputeLayout(figure).frame; }

}  // namespace locforge::plot

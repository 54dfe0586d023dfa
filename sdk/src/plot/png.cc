// PNG renderer: a small RGB canvas (lines, dots, a 5x7 bitmap font) encoded
// with zlib. Same layout as the SVG (layout.h), so both show the same plot.
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "layout.h"
#include "locforge/error.h"
#include "locforge/plot.h"

namespace locforge::plot {
namespace {

using Rgb = std::array<uint8_t, 3>;

// Printable ASCII 32..126, 5 columns per glyph, bit 0 = top row (the classic
// HD44780-style 5x7 font).
constexpr uint8_t kFont[95][5] = {
    {0x00, 0x00, 0x00, 0x00, 0x00}, {0x00, 0x00, 0x5f, 0x00, 0x00}, {0x00, 0x07, 0x00, 0x07, 0x00},
    {0x14, 0x7f, 0x14, 0x7f, 0x14}, {0x24, 0x2a, 0x7f, 0x2a, 0x12}, {0x23, 0x13, 0x08, 0x64, 0x62},
    {0x36, 0x49, 0x55, 0x22, 0x50}, {0x00, 0x05, 0x03, 0x00, 0x00}, {0x00, 0x1c, 0x22, 0x41, 0x00},
    {0x00, 0x41, 0x22, 0x1c, 0x00}, {0x14, 0x08, 0x3e, 0x08, 0x14}, {0x08, 0x08, 0x3e, 0x08, 0x08},
    {0x00, 0x50, 0x30, 0x00, 0x00}, {0x08, 0x08, 0x08, 0x08, 0x08}, {0x00, 0x60, 0x60, 0x00, 0x00},
    {0x20, 0x10, 0x08, 0x04, 0x02}, {0x3e, 0x51, 0x49, 0x45, 0x3e}, {0x00, 0x42, 0x7f, 0x40, 0x00},
    {0x42, 0x61, 0x51, 0x49, 0x46}, {0x21, 0x41, 0x45, 0x4b, 0x31}, {0x18, 0x14, 0x12, 0x7f, 0x10},
    {0x27, 0x45, 0x45, 0x45, 0x39}, {0x3c, 0x4a, 0x49, 0x49, 0x30}, {0x01, 0x71, 0x09, 0x05, 0x03},
    {0x36, 0x49, 0x49, 0x49, 0x36}, {0x06, 0x49, 0x49, 0x29, 0x1e}, {0x00, 0x36, 0x36, 0x00, 0x00},
    {0x00, 0x56, 0x36, 0x00, 0x00}, {0x08, 0x14, 0x22, 0x41, 0x00}, {0x14, 0x14, 0x14, 0x14, 0x14},
    {0x00, 0x41, 0x22, 0x14, 0x08}, {0x02, 0x01, 0x51, 0x09, 0x06}, {0x32, 0x49, 0x79, 0x41, 0x3e},
    {0x7e, 0x11, 0x11, 0x11, 0x7e}, {0x7f, 0x49, 0x49, 0x49, 0x36}, {0x3e, 0x41, 0x41, 0x41, 0x22},
    {0x7f, 0x41, 0x41, 0x22, 0x1c}, {0x7f, 0x49, 0x49, 0x49, 0x41}, {0x7f, 0x09, 0x09, 0x09, 0x01},
    {0x3e, 0x41, 0x49, 0x49, 0x7a}, {0x7f, 0x08, 0x08, 0x08, 0x7f}, {0x00, 0x41, 0x7f, 0x41, 0x00},
    {0x20, 0x40, 0x41, 0x3f, 0x01}, {0x7f, 0x08, 0x14, 0x22, 0x41}, {0x7f, 0x40, 0x40, 0x40, 0x40},
    {0x7f, 0x02, 0x0c, 0x02, 0x7f}, {0x7f, 0x04, 0x08, 0x10, 0x7f}, {0x3e, 0x41, 0x41, 0x41, 0x3e},
    {0x7f, 0x09, 0x09, 0x09, 0x06}, {0x3e, 0x41, 0x51, 0x21, 0x5e}, {0x7f, 0x09, 0x19, 0x29, 0x46},
    {0x46, 0x49, 0x49, 0x49, 0x31}, {0x01, 0x01, 0x7f, 0x01, 0x01}, {0x3f, 0x40, 0x40, 0x40, 0x3f},
    {0x1f, 0x20, 0x40, 0x20, 0x1f}, {0x3f, 0x40, 0x38, 0x40, 0x3f}, {0x63, 0x14, 0x08, 0x14, 0x63},
    {0x07, 0x08, 0x70, 0x08, 0x07}, {0x61, 0x51, 0x49, 0x45, 0x43}, {0x00, 0x7f, 0x41, 0x41, 0x00},
    {0x02, 0x04, 0x08, 0x10, 0x20}, {0x00, 0x41, 0x41, 0x7f, 0x00}, {0x04, 0x02, 0x01, 0x02, 0x04},
    {0x40, 0x40, 0x40, 0x40, 0x40}, {0x00, 0x01, 0x02, 0x04, 0x00}, {0x20, 0x54, 0x54, 0x54, 0x78},
    {0x7f, 0x48, 0x44, 0x44, 0x38}, {0x38, 0x44, 0x44, 0x44, 0x20}, {0x38, 0x44, 0x44, 0x48, 0x7f},
    {0x38, 0x54, 0x54, 0x54, 0x18}, {0x08, 0x7e, 0x09, 0x01, 0x02}, {0x0c, 0x52, 0x52, 0x52, 0x3e},
    {0x7f, 0x08, 0x04, 0x04, 0x78}, {0x00, 0x44, 0x7d, 0x40, 0x00}, {0x20, 0x40, 0x44, 0x3d, 0x00},
    {0x7f, 0x10, 0x28, 0x44, 0x00}, {0x00, 0x41, 0x7f, 0x40, 0x00}, {0x7c, 0x04, 0x18, 0x04, 0x78},
    {0x7c, 0x08, 0x04, 0x04, 0x78}, {0x38, 0x44, 0x44, 0x44, 0x38}, {0x7c, 0x14, 0x14, 0x14, 0x08},
    {0x08, 0x14, 0x14, 0x18, 0x7c}, {0x7c, 0x08, 0x04, 0x04, 0x08}, {0x48, 0x54, 0x54, 0x54, 0x20},
    {0x04, 0x3f, 0x44, 0x40, 0x20}, {0x3c, 0x40, 0x40, 0x20, 0x7c}, {0x1c, 0x20, 0x40, 0x20, 0x1c},
    {0x3c, 0x40, 0x30, 0x40, 0x3c}, {0x44, 0x28, 0x10, 0x28, 0x44}, {0x0c, 0x50, 0x50, 0x50, 0x3c},
    {0x44, 0x64, 0x54, 0x4c, 0x44}, {0x00, 0x08, 0x36, 0x41, 0x00}, {0x00, 0x00, 0x7f, 0x00, 0x00},
    {0x00, 0x41, 0x36, 0x08, 0x00}, {0x10, 0x08, 0x08, 0x10, 0x08}};

constexpr int kGlyphScale = 2;                    // 5x7 -> 10x14 pixels
constexpr int kAdvance = 6 * kGlyphScale;         // glyph + one column of space

class Canvas {
 public:
  Canvas(int width, int height) : w_(width), h_(height), rgb_(3 * size_t(width) * height, 255) {}

  void Set(int x, int y, const Rgb& c) {
    if (x < clip_x0_ || y < clip_y0_ || x >= clip_x1_ || y >= clip_y1_) return;
    std::copy(c.begin(), c.end(), rgb_.begin() + 3 * (size_t(y) * w_ + x));
  }
  void Clip(int x0, int y0, int x1, int y1) {
    clip_x0_ = std::max(0, x0), clip_y0_ = std::max(0, y0);
    clip_x1_ = std::min(w_, x1), clip_y1_ = std::min(h_, y1);
  }
  void Unclip() { Clip(0, 0, w_, h_); }

  // A line of `thickness` pixels; dashed = 6 on, 4 off (as the SVG).
  void Line(Eigen::Vector2d a, Eigen::Vector2d b, const Rgb& c, int thickness, bool dashed) {
    const double length = (b - a).norm();
    const int steps = std::max(1, static_cast<int>(std::ceil(length * 2)));
    // Offsets past the clip area cost nothing but time: bound absurd lengths.
    if (steps > 200000) return;
    for (int i = 0; i <= steps; ++i) {
      const double s = static_cast<double>(i) / steps;
      if (dashed && std::fmod(s * length, 10.0) >= 6.0) continue;
      const Eigen::Vector2d p = a + s * (b - a);
      Dot(p, c, thickness);
    }
  }
  void Dot(const Eigen::Vector2d& p, const Rgb& c, int diameter) {
    const double r = 0.5 * diameter;
    for (int y = static_cast<int>(std::floor(p.y() - r)); y <= static_cast<int>(std::ceil(p.y() + r)); ++y) {
      for (int x = static_cast<int>(std::floor(p.x() - r)); x <= static_cast<int>(std::ceil(p.x() + r)); ++x) {
        const double dx = x + 0.5 - p.x(), dy = y + 0.5 - p.y();
        if (dx * dx + dy * dy <= r * r + 0.25) Set(x, y, c);
      }
    }
  }
  // Text with its baseline-left at (x, y); vertical = rotated 90 deg
  // counter-clockwise (reads bottom to top, as a y-axis label).
  void Text(const std::string& text, int x, int y, const Rgb& c, bool vertical = false) {
    int pen = 0;
    for (char ch : text) {
      const int code = static_cast<unsigned char>(ch);
      const uint8_t* glyph = kFont[(code >= 32 && code < 127) ? code - 32 : '?' - 32];
      for (int col = 0; col < 5; ++col) {
        for (int row = 0; row < 7; ++row) {
          if (!(glyph[col] >> row & 1)) continue;
          for (int sy = 0; sy < kGlyphScale; ++sy) {
            for (int sx = 0; sx < kGlyphScale; ++sx) {
              const int gx = pen + col * kGlyphScale + sx;
              const int gy = (row - 7) * kGlyphScale + sy;  // above the baseline
              if (vertical) Set(x + gy, y - gx, c);
              else Set(x + gx, y + gy, c);
            }
          }
        }
      }
      pen += kAdvance;
    }
  }

  std::vector<uint8_t> EncodePng() const;

 private:
  int w_, h_;
  int clip_x0_ = 0, clip_y0_ = 0, clip_x1_ = w_, clip_y1_ = h_;
  std::vector<uint8_t> rgb_;
};

int TextWidth(const std::string& text) { return static_cast<int>(text.size()) * kAdvance; }

void PutU32(std::vector<uint8_t>* out, uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out->push_back(static_cast<uint8_t>(v >> shift));
}

void PutChunk(std::vector<uint8_t>* out, const char type[4], const std::vector<uint8_t>& data) {
  PutU32(out, static_cast<uint32_t>(data.size()));
  const size_t start = out->size();
  out->insert(out->end(), type, type + 4);
  out->insert(out->end(), data.begin(), data.end());
  const uLong crc = crc32(0L, out->data() + start, static_cast<uInt>(out->size() - start));
  PutU32(out, static_cast<uint32_t>(crc));
}

std::vector<uint8_t> Canvas::EncodePng() const {
  // Scanlines, each prefixed with filter type 0 (none); zlib does the rest.
  std::vector<uint8_t> raw;
  raw.reserve((3 * size_t(w_) + 1) * h_);
  for (int y = 0; y < h_; ++y) {
    raw.push_back(0);
    raw.insert(raw.end(), rgb_.begin() + 3 * size_t(y) * w_, rgb_.begin() + 3 * size_t(y + 1) * w_);
  }
  uLongf packed_size = compressBound(raw.size());
  std::vector<uint8_t> packed(packed_size);
  if (compress2(packed.data(), &packed_size, raw.data(), raw.size(), 6) != Z_OK) {
    throw Error("PNG encoding failed (zlib)");
  }
  packed.resize(packed_size);

  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<uint8_t> header;
  PutU32(&header, static_cast<uint32_t>(w_));
  PutU32(&header, static_cast<uint32_t>(h_));
  header.insert(header.end(), {8, 2, 0, 0, 0});  // 8 bit, RGB, deflate, no filter, no interlace
  PutChunk(&png, "IHDR", header);
  PutChunk(&png, "IDAT", packed);
  PutChunk(&png, "IEND", {});
  return png;
}

}  // namespace

std::vector<uint8_t> RenderPng(const Figure& figure) {
  if (figure.width < 100 || figure.height < 100 || figure.width > 10000 || figure.height > 10000) {
    throw Error("figure size " + std::to_string(figure.width) + "x" + std::to_string(figure.height) +
                " is outside 100..10000 pixels");
  }
  const Frame f = ComputeFrame(figure);
  Canvas canvas(figure.width, figure.height);
  const Rgb black{0, 0, 0}, grid{224, 224, 224};

  const std::vector<double> xt = internal::Ticks(f.x_min, f.x_max, 8);
  const std::vector<double> yt = internal::Ticks(f.y_min, f.y_max, 6);
  for (double x : xt) {
    const double u = f.ToPixel(x, f.y_min).x();
    canvas.Line({u, double(f.top)}, {u, double(f.bottom)}, grid, 1, false);
    const std::string label = internal::TickLabel(x, xt.size() > 1 ? xt[1] - xt[0] : 1.0);
    canvas.Text(label, static_cast<int>(u) - TextWidth(label) / 2, f.bottom + 20, black);
  }
  for (double y : yt) {
    const double v = f.ToPixel(f.x_min, y).y();
    canvas.Line({double(f.left), v}, {double(f.right), v}, grid, 1, false);
    const std::string label = internal::TickLabel(y, yt.size() > 1 ? yt[1] - yt[0] : 1.0);
    canvas.Text(label, f.left - 6 - TextWidth(label), static_cast<int>(v) + 7, black);
  }

  canvas.Clip(f.left, f.top, f.right, f.bottom);
  for (const Segment& s : figure.segments) {
    canvas.Line(f.ToPixel(s.x0, s.y0), f.ToPixel(s.x1, s.y1), internal::ParseColor(s.color), 1, false);
  }
  for (size_t i = 0; i < figure.series.size(); ++i) {
    const Series& s = figure.series[i];
    const Rgb color = internal::ParseColor(internal::SeriesColor(figure, i));
    const size_t n = std::min(s.x.size(), s.y.size());
    for (size_t k = 0; k < n; ++k) {
      if (!std::isfinite(s.x[k]) || !std::isfinite(s.y[k])) continue;
      const Eigen::Vector2d p = f.ToPixel(s.x[k], s.y[k]);
      if (s.line && k + 1 < n && std::isfinite(s.x[k + 1]) && std::isfinite(s.y[k + 1])) {
        canvas.Line(p, f.ToPixel(s.x[k + 1], s.y[k + 1]), color, 2, s.dashed);
      }
      if (s.markers || !s.line) canvas.Dot(p, color, 6);
    }
  }
  canvas.Unclip();
  for (int x = f.left; x <= f.right; ++x) canvas.Set(x, f.top, black), canvas.Set(x, f.bottom, black);
  for (int y = f.top; y <= f.bottom; ++y) canvas.Set(f.left, y, black), canvas.Set(f.right, y, black);

  // Legend: a white box in the top-right corner of the plot area.
  int rows = 0, widest = 0;
  for (const Series& s : figure.series) {
    if (!s.label.empty()) ++rows, widest = std::max(widest, TextWidth(s.label));
  }
  if (rows > 0) {
    const int w = widest + 44, h = 6 + 20 * rows;
    const Eigen::Vector2d origin = internal::LegendOrigin(figure, f, w, h);
    const int x0 = static_cast<int>(origin.x()), y0 = static_cast<int>(origin.y());
    const int x1 = x0 + w, y1 = y0 + h;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x)
        canvas.Set(x, y, (y == y0 || y == y1 || x == x0 || x == x1) ? Rgb{160, 160, 160} : Rgb{255, 255, 255});
    int row = 0;
    for (size_t i = 0; i < figure.series.size(); ++i) {
      if (figure.series[i].label.empty()) continue;
      const int y = y0 + 21 + 20 * row++;
      const Rgb color = internal::ParseColor(internal::SeriesColor(figure, i));
      canvas.Line({x0 + 6.0, y - 6.0}, {x0 + 30.0, y - 6.0}, color, 3, figure.series[i].dashed);
      canvas.Text(figure.series[i].label, x0 + 38, y, black);
    }
  }
  canvas.Text(figure.title, (f.left + f.right - TextWidth(figure.title)) / 2, 26, black);
  canvas.Text(figure.x_label, (f.left + f.right - TextWidth(figure.x_label)) / 2, figure.height - 8,
              black);
  canvas.Text(figure.y_label, 24, (f.top + f.bottom + TextWidth(figure.y_label)) / 2, black, true);
  return canvas.EncodePng();
}

}  // namespace locforge::plot

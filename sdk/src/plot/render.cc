// The one drawing of a figure (Cairo), rendered to PNG and to SVG, and
// WriteFigure. Geometry comes from layout.cc, so both formats and
// ComputeFrame agree to the pixel.
#include <cairo-svg.h>
#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>

#include "font.h"
#include "layout.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/plot.h"

namespace locforge::plot {
namespace {

using internal::Layout;
using internal::LegendEntry;
using internal::Rgba;

const Rgba kBlack{0, 0, 0, 1};
const Rgba kGrid{0.898, 0.898, 0.898, 1};         // #e5e5e5
const Rgba kLegendBorder{0.8, 0.8, 0.8, 1};       // #cccccc
const Rgba kLegendFill{1, 1, 1, 0.9};

void SetColor(cairo_t* cr, const Rgba& c) { cairo_set_source_rgba(cr, c.r, c.g, c.b, c.a); }

// A 1-pixel line through pixel centres, so it covers one column, not two halves.
double Crisp(double v) { return std::floor(v) + 0.5; }

class Painter {
 public:
  Painter(cairo_t* cr, const Figure& figure, const Layout& layout, bool raster)
      : cr_(cr), figure_(figure), layout_(layout), raster_(raster) {}

  void Draw() {
    const Frame& f = layout_.frame;
    cairo_set_source_rgb(cr_, 1, 1, 1);
    cairo_paint(cr_);
    Grid();
    Box();
    // The data goes over the box, clipped a little outside it: a curve along
    // an axis limit (a recall of 100 %) stays visible instead of half hidden.
    cairo_save(cr_);
    const double spill = 2;
    cairo_rectangle(cr_, f.left - spill, f.top - spill, f.right - f.left + 2 * spill, f.bottom - f.top + 2 * spill);
    cairo_clip(cr_);
    Segments();
    for (size_t i = 0; i < figure_.series.size(); ++i) SeriesLine(i);
    for (size_t i = 0; i < figure_.series.size(); ++i) SeriesMarkers(i);
    cairo_restore(cr_);
    Axes();
    Legend();
    Titles();
  }

 private:
  enum class Align { kLeft, kCenter, kRight };

  // Text with its baseline at y; angle in radians (-pi/2 reads bottom to top).
  void Text(const std::string& text, double size, double x, double y, Align align, double angle = 0) {
    if (text.empty()) return;
    internal::SetFont(cr_, size, raster_);
    cairo_text_extents_t e;
    cairo_text_extents(cr_, text.c_str(), &e);
    const double dx = align == Align::kLeft ? 0 : align == Align::kCenter ? -0.5 * e.x_advance : -e.x_advance;
    cairo_save(cr_);
    // Whole pixels for the origin: the hinted glyphs then sit on the grid.
    cairo_translate(cr_, std::round(x), std::round(y));
    cairo_rotate(cr_, angle);
    cairo_move_to(cr_, std::round(dx), 0);
    SetColor(cr_, kBlack);
    cairo_show_text(cr_, text.c_str());
    cairo_restore(cr_);
  }

  void Grid() {
    const Frame& f = layout_.frame;
    cairo_set_line_width(cr_, 1);
    SetColor(cr_, kGrid);
    for (double x : layout_.x_ticks) {
      const double u = Crisp(f.ToPixel(x, f.y_min).x());
      cairo_move_to(cr_, u, f.top);
      cairo_line_to(cr_, u, f.bottom);
    }
    for (double y : layout_.y_ticks) {
      const double v = Crisp(f.ToPixel(f.x_min, y).y());
      cairo_move_to(cr_, f.left, v);
      cairo_line_to(cr_, f.right, v);
    }
    cairo_stroke(cr_);
  }

  // Coordinates handed to Cairo stay within the plot area plus a border wide
  // enough for line joins, markers and wide lines.
  bool Clip(Eigen::Vector2d* a, Eigen::Vector2d* b) const {
    const Frame& f = layout_.frame;
    const double border = 120;
    return internal::ClipSegment(a, b, f.left - border, f.top - border, f.right + border, f.bottom + border);
  }

  // One stroke each: where translucent segments overlap, the colour deepens.
  void Segments() {
    const Frame& f = layout_.frame;
    cairo_set_line_width(cr_, 1);
    cairo_set_line_cap(cr_, CAIRO_LINE_CAP_ROUND);
    for (const Segment& s : figure_.segments) {
      Eigen::Vector2d a = f.ToPixel(s.x0, s.y0), b = f.ToPixel(s.x1, s.y1);
      if (!a.allFinite() || !b.allFinite() || !Clip(&a, &b)) continue;
      cairo_move_to(cr_, a.x(), a.y());
      cairo_line_to(cr_, b.x(), b.y());
      SetColor(cr_, internal::ParseColor(s.color, "segment"));
      cairo_stroke(cr_);
    }
  }

  void SetLineStyle(double width, bool dashed) {
    cairo_set_line_width(cr_, width);
    cairo_set_line_join(cr_, CAIRO_LINE_JOIN_ROUND);
    if (dashed) {
      const double dashes[] = {3.5 * width, 2 * width};
      cairo_set_dash(cr_, dashes, 2, 0);
      cairo_set_line_cap(cr_, CAIRO_LINE_CAP_BUTT);
    } else {
      cairo_set_dash(cr_, nullptr, 0, 0);
      cairo_set_line_cap(cr_, CAIRO_LINE_CAP_ROUND);
    }
  }

  void SeriesLine(size_t index) {
    const Series& s = figure_.series[index];
    if (!s.line) return;
    const Frame& f = layout_.frame;
    bool open = false;  // the path continues at the current point
    Eigen::Vector2d last;
    for (size_t k = 0; k + 1 < s.x.size(); ++k) {
      if (!std::isfinite(s.x[k]) || !std::isfinite(s.y[k]) || !std::isfinite(s.x[k + 1]) ||
          !std::isfinite(s.y[k + 1])) {
        open = false;
        continue;
      }
      Eigen::Vector2d a = f.ToPixel(s.x[k], s.y[k]), b = f.ToPixel(s.x[k + 1], s.y[k + 1]);
      const Eigen::Vector2d b_before = b;
      if (!a.allFinite() || !b.allFinite() || !Clip(&a, &b)) {
        open = false;
        continue;
      }
      if (!open || a != last) cairo_move_to(cr_, a.x(), a.y());
      cairo_line_to(cr_, b.x(), b.y());
      last = b;
      open = b == b_before;
    }
    SetColor(cr_, internal::ParseColor(internal::SeriesColor(figure_, index), "series"));
    SetLineStyle(internal::kLineWidth, s.dashed);
    cairo_stroke(cr_);
    cairo_set_dash(cr_, nullptr, 0, 0);
  }

  void DotPath(const Eigen::Vector2d& p) {
    cairo_new_sub_path(cr_);
    cairo_arc(cr_, p.x(), p.y(), internal::kDotRadius, 0, 2 * M_PI);
  }

  void SeriesMarkers(size_t index) {
    const Series& s = figure_.series[index];
    if (!s.markers && s.line) return;
    const Frame& f = layout_.frame;
    const double r = internal::kDotRadius;
    for (size_t k = 0; k < s.x.size(); ++k) {
      if (!std::isfinite(s.x[k]) || !std::isfinite(s.y[k])) continue;
      const Eigen::Vector2d p = f.ToPixel(s.x[k], s.y[k]);
      if (!p.allFinite() || p.x() < f.left - 2 * r || p.x() > f.right + 2 * r || p.y() < f.top - 2 * r || p.y() > f.bottom + 2 * r)
        continue;
      DotPath(p);
    }
    SetColor(cr_, internal::ParseColor(internal::SeriesColor(figure_, index), "series"));
    cairo_fill(cr_);
  }

  // The plot area's frame, 1 pixel just outside it.
  void Box() {
    const Frame& f = layout_.frame;
    SetColor(cr_, kBlack);
    cairo_set_line_width(cr_, 1);
    cairo_rectangle(cr_, f.left - 0.5, f.top - 0.5, f.right - f.left + 1, f.bottom - f.top + 1);
    cairo_stroke(cr_);
  }

  // Ticks (outward) and their labels.
  void Axes() {
    const Frame& f = layout_.frame;
    const internal::TextSize digits = internal::MeasureText("0", internal::kTickFont);
    SetColor(cr_, kBlack);
    cairo_set_line_width(cr_, 1);
    cairo_set_line_cap(cr_, CAIRO_LINE_CAP_BUTT);
    for (double x : layout_.x_ticks) {
      const double u = Crisp(f.ToPixel(x, f.y_min).x());
      cairo_move_to(cr_, u, f.bottom + 0.5);
      cairo_line_to(cr_, u, f.bottom + 0.5 + internal::kTickLength);
    }
    for (double y : layout_.y_ticks) {
      const double v = Crisp(f.ToPixel(f.x_min, y).y());
      cairo_move_to(cr_, f.left - 0.5, v);
      cairo_line_to(cr_, f.left - 0.5 - internal::kTickLength, v);
    }
    for (double x : layout_.x_minor) {
      const double u = Crisp(f.ToPixel(x, f.y_min).x());
      cairo_move_to(cr_, u, f.bottom + 0.5);
      cairo_line_to(cr_, u, f.bottom + 0.5 + 0.6 * internal::kTickLength);
    }
    for (double y : layout_.y_minor) {
      const double v = Crisp(f.ToPixel(f.x_min, y).y());
      cairo_move_to(cr_, f.left - 0.5, v);
      cairo_line_to(cr_, f.left - 0.5 - 0.6 * internal::kTickLength, v);
    }
    cairo_stroke(cr_);
    for (size_t i = 0; i < layout_.x_ticks.size(); ++i) {
      Text(layout_.x_labels[i], internal::kTickFont, f.ToPixel(layout_.x_ticks[i], f.y_min).x(),
           f.bottom + internal::kTickLength + 4 + digits.digit_height, Align::kCenter);
    }
    for (size_t i = 0; i < layout_.y_ticks.size(); ++i) {
      Text(layout_.y_labels[i], internal::kTickFont, f.left - internal::kTickLength - 4,
           f.ToPixel(f.x_min, layout_.y_ticks[i]).y() + 0.5 * digits.digit_height, Align::kRight);
    }
  }

  void Titles() {
    const Frame& f = layout_.frame;
    const internal::TextSize label = internal::MeasureText("x", internal::kLabelFont);
    Text(internal::CleanText(figure_.x_label), internal::kLabelFont, 0.5 * (f.left + f.right),
         figure_.height - internal::kPad - label.descent, Align::kCenter);
    Text(internal::CleanText(figure_.y_label), internal::kLabelFont, internal::kPad + label.ascent,
         0.5 * (f.top + f.bottom), Align::kCenter, -0.5 * M_PI);
    const std::string title = internal::CleanText(figure_.title);
    if (title.empty()) return;
    const internal::TextSize t = internal::MeasureText(title, layout_.title_size);
    // Centred over the plot area, moved in when that would cut it.
    const double x = std::clamp(0.5 * (f.left + f.right - t.width), internal::kPad,
                                std::max(internal::kPad, figure_.width - internal::kPad - t.width));
    Text(title, layout_.title_size, x, internal::kPad + t.ascent, Align::kLeft);
  }

  void Legend() {
    if (layout_.legend.empty()) return;
    const double x0 = layout_.legend_x, y0 = layout_.legend_y;
    const double radius = 3;
    {
      // The 1-pixel border through pixel centres.
      const double x = x0 + 0.5, y = y0 + 0.5, w = layout_.legend_w - 1, h = layout_.legend_h - 1;
      cairo_new_sub_path(cr_);
      cairo_arc(cr_, x + w - radius, y + radius, radius, -0.5 * M_PI, 0);
      cairo_arc(cr_, x + w - radius, y + h - radius, radius, 0, 0.5 * M_PI);
      cairo_arc(cr_, x + radius, y + h - radius, radius, 0.5 * M_PI, M_PI);
      cairo_arc(cr_, x + radius, y + radius, radius, M_PI, 1.5 * M_PI);
      cairo_close_path(cr_);
    }
    SetColor(cr_, kLegendFill);
    cairo_fill_preserve(cr_);
    SetColor(cr_, kLegendBorder);
    cairo_set_line_width(cr_, 1);
    cairo_stroke(cr_);
    const internal::TextSize digits = internal::MeasureText("0", internal::kLegendFont);
    for (size_t i = 0; i < layout_.legend.size(); ++i) {
      const LegendEntry& e = layout_.legend[i];
      const double y = std::round(y0 + 0.5 * internal::kLegendPad + (i + 0.5) * layout_.legend_row);
      const double xs = x0 + internal::kLegendPad;
      SetColor(cr_, e.color);
      if (e.line) {
        SetLineStyle(internal::kLineWidth, e.dashed);
        cairo_move_to(cr_, xs, y);
        cairo_line_to(cr_, xs + internal::kLegendSample, y);
        cairo_stroke(cr_);
        cairo_set_dash(cr_, nullptr, 0, 0);
      }
      if (e.markers) {
        DotPath({xs + 0.5 * internal::kLegendSample, y});
        cairo_fill(cr_);
      }
      Text(e.label, internal::kLegendFont, xs + internal::kLegendSample + 8, y + 0.5 * digits.digit_height,
           Align::kLeft);
    }
  }

  cairo_t* cr_;
  const Figure& figure_;
  const Layout& layout_;
  bool raster_;
};

using SurfacePtr = std::unique_ptr<cairo_surface_t, decltype(&cairo_surface_destroy)>;
using ContextPtr = std::unique_ptr<cairo_t, decltype(&cairo_destroy)>;

void Paint(const Figure& figure, const Layout& layout, cairo_surface_t* surface, bool raster) {
  ContextPtr cr(cairo_create(surface), cairo_destroy);
  Painter(cr.get(), figure, layout, raster).Draw();
  if (cairo_status(cr.get()) != CAIRO_STATUS_SUCCESS) {
    throw Error("drawing figure '" + figure.title + "' failed: " + cairo_status_to_string(cairo_status(cr.get())));
  }
}

cairo_status_t Append(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

std::string EscapeXml(const std::string& text) {
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

// Cairo names its elements with process-wide counters ("surface6"): renamed
// here in order of appearance, with a prefix hashed from the document, so the
// same figure gives the same bytes and different figures never share an id
// when inlined in one HTML page.
std::string RenameIds(const std::string& svg) {
  const std::string kId = "id=\"", kHref = "href=\"#", kUrl = "url(#";
  std::map<std::string, size_t> names;
  for (size_t at = svg.find(kId); at != std::string::npos; at = svg.find(kId, at + 1)) {
    if (at > 0 && svg[at - 1] != ' ' && svg[at - 1] != '\n') continue;  // e.g. "xml:id"
    const size_t start = at + kId.size(), end = svg.find('"', start);
    if (end == std::string::npos) break;
    names.emplace(svg.substr(start, end - start), names.size());
  }
  const char kPlaceholder = '\x01';  // never in Cairo's output
  std::string out;
  out.reserve(svg.size());
  for (size_t i = 0; i < svg.size();) {
    const std::string* prefix = nullptr;
    for (const std::string* p : {&kId, &kHref, &kUrl}) {
      if (svg.compare(i, p->size(), *p) == 0) prefix = p;
    }
    if (!prefix) {
      out += svg[i++];
      continue;
    }
    const size_t start = i + prefix->size();
    const size_t end = svg.find_first_of(prefix == &kUrl ? ")" : "\"", start);
    const auto it = end == std::string::npos ? names.end() : names.find(svg.substr(start, end - start));
    out += *prefix;
    if (it != names.end()) {
      out += kPlaceholder + std::to_string(it->second);
      i = end;
    } else {
      i = start;
    }
  }
  uint64_t hash = 1469598103934665603ull;  // FNV-1a
  for (unsigned char c : out) hash = (hash ^ c) * 1099511628211ull;
  char id_prefix[32];
  std::snprintf(id_prefix, sizeof(id_prefix), "lf%012llx-",
                static_cast<unsigned long long>(hash & 0xffffffffffffull));
  std::string result;
  result.reserve(out.size() + 16 * names.size());
  for (char c : out) {
    if (c == kPlaceholder) result += id_prefix;
    else result += c;
  }
  return result;
}

}  // namespace

std::vector<uint8_t> RenderPng(const Figure& figure) {
  const Layout layout = internal::ComputeLayout(figure);
  SurfacePtr surface(cairo_image_surface_create(CAIRO_FORMAT_RGB24, figure.width, figure.height),
                     cairo_surface_destroy);
  Paint(figure, layout, surface.get(), true);
  std::string bytes;
  const cairo_status_t status = cairo_surface_write_to_png_stream(surface.get(), Append, &bytes);
  if (status != CAIRO_STATUS_SUCCESS) {
    throw Error("PNG encoding of figure '" + figure.title + "' failed: " + cairo_status_to_string(status));
  }
  return std::vector<uint8_t>(bytes.begin(), bytes.end());
}

std::string RenderSvg(const Figure& figure) {
  const Layout layout = internal::ComputeLayout(figure);
  std::string svg;
  SurfacePtr surface(cairo_svg_surface_create_for_stream(Append, &svg, figure.width, figure.height),
                     cairo_surface_destroy);
  cairo_svg_surface_set_document_unit(surface.get(), CAIRO_SVG_UNIT_PX);
  Paint(figure, layout, surface.get(), false);
  cairo_surface_finish(surface.get());
  if (cairo_surface_status(surface.get()) != CAIRO_STATUS_SUCCESS) {
    throw Error("SVG output of figure '" + figure.title +
                "' failed: " + cairo_status_to_string(cairo_surface_status(surface.get())));
  }
  // The title, for screen readers and browsers' tooltips.
  const size_t open = svg.find("<svg");
  const size_t close = open == std::string::npos ? open : svg.find('>', open);
  if (close != std::string::npos && !figure.title.empty()) {
    svg.insert(close + 1, "\n<title>" + EscapeXml(internal::CleanText(figure.title)) + "</title>");
  }
  return RenameIds(svg);
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

#include "locforge/plot.h"

#include <cairo.h>
#include <expat.h>
#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <thread>

#include "font.h"
#include "layout.h"
#include "locforge/error.h"

extern char** environ;

namespace locforge::plot {
namespace {

using Rgb = std::array<int, 3>;

// A PNG decoded by Cairo's own reader (libpng underneath).
struct Image {
  int width = 0, height = 0;
  std::vector<uint32_t> pixels;  // 0x00rrggbb
  Rgb At(int x, int y) const {
    const uint32_t p = pixels[size_t(y) * width + x];
    return {int(p >> 16 & 0xff), int(p >> 8 & 0xff), int(p & 0xff)};
  }
};

Image DecodePng(const std::vector<uint8_t>& png) {
  Image image;
  EXPECT_GT(png.size(), 33u);
  if (png.size() < 33) return image;
  EXPECT_EQ(std::vector<uint8_t>(png.begin(), png.begin() + 8),
            (std::vector<uint8_t>{0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'}));
  EXPECT_EQ(std::string(png.begin() + 12, png.begin() + 16), "IHDR");
  EXPECT_EQ(png[24], 8);  // bit depth
  EXPECT_EQ(png[25], 2);  // colour type RGB
  struct Reader {
    const std::vector<uint8_t>* bytes;
    size_t at = 0;
  } reader{&png};
  auto read = [](void* closure, unsigned char* data, unsigned int length) {
    auto* r = static_cast<Reader*>(closure);
    if (r->at + length > r->bytes->size()) return CAIRO_STATUS_READ_ERROR;
    std::memcpy(data, r->bytes->data() + r->at, length);
    r->at += length;
    return CAIRO_STATUS_SUCCESS;
  };
  cairo_surface_t* surface = cairo_image_surface_create_from_png_stream(read, &reader);
  EXPECT_EQ(cairo_surface_status(surface), CAIRO_STATUS_SUCCESS);
  if (cairo_surface_status(surface) == CAIRO_STATUS_SUCCESS) {
    cairo_surface_flush(surface);
    image.width = cairo_image_surface_get_width(surface);
    image.height = cairo_image_surface_get_height(surface);
    const int stride = cairo_image_surface_get_stride(surface);
    const unsigned char* data = cairo_image_surface_get_data(surface);
    for (int y = 0; y < image.height; ++y) {
      const auto* row = reinterpret_cast<const uint32_t*>(data + size_t(y) * stride);
      for (int x = 0; x < image.width; ++x) image.pixels.push_back(row[x] & 0xffffff);
    }
  }
  cairo_surface_destroy(surface);
  return image;
}

Rgb Hex(const std::string& hex) {
  const internal::Rgba c = internal::ParseColor(hex, "test");
  return {int(std::lround(255 * c.r)), int(std::lround(255 * c.g)), int(std::lround(255 * c.b))};
}

bool Near(const Rgb& a, const Rgb& b, int tolerance) {
  for (int i = 0; i < 3; ++i)
    if (std::abs(a[i] - b[i]) > tolerance) return false;
  return true;
}

bool Dark(const Rgb& c) { return c[0] < 110 && c[1] < 110 && c[2] < 110; }

// Dark (text) pixels in the rectangle [x0, x1) x [y0, y1), clamped to the image.
int DarkPixels(const Image& image, int x0, int y0, int x1, int y1) {
  int n = 0;
  for (int y = std::max(0, y0); y < std::min(image.height, y1); ++y)
    for (int x = std::max(0, x0); x < std::min(image.width, x1); ++x) n += Dark(image.At(x, y));
  return n;
}

Figure TwoSeries() {
  Figure figure;
  figure.title = "recall <vs> threshold";
  figure.x_label = "position error (m)";
  figure.y_label = "% of queries";
  figure.series.push_back({"SIFT", {0, 0.5, 1, 2}, {0, 40, 70, 90}, "", true, false, true});
  figure.series.push_back({"R2D2", {0, 0.5, 1, 2}, {0, 50, 80, 95}, "#00ff00", false, true, true});
  return figure;
}

// A map as the LiDAR stage draws it: a loop, dashed before / solid after,
// loop edges, equal aspect.
Figure Map() {
  Figure figure;
  figure.title = "Trajectories";
  figure.x_label = "x (m)";
  figure.y_label = "y (m)";
  figure.equal_aspect = true;
  figure.width = 900;
  Series before{"", {}, {}, PaletteColor(0), false, true}, after{"seq_0", {}, {}, PaletteColor(0)};
  for (int i = 0; i <= 200; ++i) {
    const double t = 2 * M_PI * i / 200;
    after.x.push_back(20 * std::cos(t));
    after.y.push_back(8 * std::sin(t));
    before.x.push_back(20 * std::cos(t) * (1 + 0.002 * i));
    before.y.push_back(8 * std::sin(t) + 0.01 * i);
  }
  figure.series = {before, after, {"before optimisation", {}, {}, "#808080", false, true}, {"loop", {}, {}, "#00000080"}};
  for (int i = 0; i < 10; ++i)
    figure.segments.push_back({after.x[i], after.y[i], after.x[200 - i], after.y[200 - i], "#00000080"});
  return figure;
}

TEST(Plot, TicksAreNiceAndCoverTheRange) {
  const std::vector<double> ticks = internal::Ticks(0, 1, 5);
  ASSERT_EQ(ticks.size(), 6u);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(ticks[i], 0.2 * i, 1e-12);
  // (12.2 + 3.7) / 6 = 2.65 -> the next nice step is 5.
  EXPECT_EQ(internal::Ticks(-3.7, 12.2, 6), (std::vector<double>{0, 5, 10}));
  EXPECT_EQ(internal::Ticks(-13.7, 12.2, 6), (std::vector<double>{-10, -5, 0, 5, 10}));
  EXPECT_EQ(internal::TickLabel(0.25, 0.05), "0.25");
  EXPECT_EQ(internal::TickLabel(250, 50), "250");
  EXPECT_EQ(internal::TickLabel(-0.0, 0.1), "0.0");
  EXPECT_EQ(internal::DisplayTickLabel(-5, 5), "\xE2\x88\x92" "5");  // U+2212 minus
}

TEST(Plot, FrameMapsDataCornersToThePlotArea) {
  Figure figure = TwoSeries();
  figure.x_min = 0, figure.x_max = 2, figure.y_min = 0, figure.y_max = 100;
  const Frame f = ComputeFrame(figure);
  EXPECT_NEAR(f.ToPixel(0, 0).x(), f.left, 1e-9);
  EXPECT_NEAR(f.ToPixel(0, 0).y(), f.bottom, 1e-9);
  EXPECT_NEAR(f.ToPixel(2, 100).x(), f.right, 1e-9);
  EXPECT_NEAR(f.ToPixel(2, 100).y(), f.top, 1e-9);
}

TEST(Plot, EqualAspectGivesOneUnitTheSameLengthOnBothAxes) {
  Figure figure;
  figure.equal_aspect = true;
  figure.series.push_back({"", {0, 40}, {0, 10}});
  const Frame f = ComputeFrame(figure);
  const double sx = (f.right - f.left) / (f.x_max - f.x_min);
  const double sy = (f.bottom - f.top) / (f.y_max - f.y_min);
  EXPECT_NEAR(sx, sy, 1e-9);
  EXPECT_LE(f.x_min, 0.0);
  EXPECT_GE(f.x_max, 40.0);
  // A map's grid is square: one tick step on both axes.
  const internal::Layout layout = internal::ComputeLayout(figure);
  EXPECT_EQ(layout.x_step, layout.y_step);
}

TEST(Plot, TheFontIsARealTypeface) {
  // fonts-dejavu-core is in cmake/debian-packages.txt.
  EXPECT_NE(internal::FontFile().find("DejaVuSans.ttf"), std::string::npos) << internal::FontFile();
  const internal::TextSize wide = internal::MeasureText("WWWW", 13), narrow = internal::MeasureText("iiii", 13);
  EXPECT_GT(wide.width, 2 * narrow.width);  // proportional, not a fixed-width bitmap
  EXPECT_NEAR(wide.ascent, 13 * 0.93, 1.0);  // DejaVu Sans: ascent 0.928 em
}

TEST(Plot, MarginsFitTheTickLabelsAndTheyNeverTouch) {
  Figure figure;
  figure.y_label = "value";
  figure.series.push_back({"", {123456, 987654}, {-123456, 987654}});
  const internal::Layout layout = internal::ComputeLayout(figure);
  const Frame& f = layout.frame;
  double widest_y = 0, widest_x = 0;
  for (const std::string& label : layout.y_labels)
    widest_y = std::max(widest_y, internal::MeasureText(label, internal::kTickFont).width);
  for (const std::string& label : layout.x_labels)
    widest_x = std::max(widest_x, internal::MeasureText(label, internal::kTickFont).width);
  EXPECT_EQ(layout.x_labels.front(), internal::DisplayTickLabel(layout.x_ticks.front(), layout.x_step));
  EXPECT_GE(f.left, widest_y + internal::kTickLength + 4 + 14);  // labels + the rotated y label
  const double spacing = layout.x_step / (f.x_max - f.x_min) * (f.right - f.left);
  EXPECT_GE(spacing, widest_x + 12);
  EXPECT_GE(layout.x_ticks.size(), 2u);
  EXPECT_GE(layout.y_ticks.size(), 3u);
}

TEST(Plot, PngShowsEachSeriesAtItsDataPoints) {
  const Figure figure = TwoSeries();
  const Image image = DecodePng(RenderPng(figure));
  ASSERT_EQ(image.width, 800);
  ASSERT_EQ(image.height, 600);
  const Frame f = ComputeFrame(figure);
  const Rgb sift = Hex(PaletteColor(0));
  for (size_t k = 1; k < 4; ++k) {  // k = 0 is under the other series' first point
    const Eigen::Vector2d p = f.ToPixel(figure.series[0].x[k], figure.series[0].y[k]);
    EXPECT_EQ(image.At(int(p.x()), int(p.y())), sift) << "point " << k;  // inside a marker
  }
  // The dashed green series: most of the samples along its first segment are green.
  const Eigen::Vector2d a = f.ToPixel(0, 0), b = f.ToPixel(0.5, 50);
  int green = 0;
  for (int i = 0; i <= 100; ++i) {
    const Eigen::Vector2d p = a + (b - a) * (i / 100.0);
    green += Near(image.At(int(p.x()), int(p.y())), {0, 255, 0}, 60);
  }
  EXPECT_GT(green, 40);
  EXPECT_LT(green, 90);  // dashed: gaps
  // Background stays white away from the data; text is drawn (dark pixels in the title band).
  EXPECT_EQ(image.At(f.right - 5, f.bottom - 5), (Rgb{255, 255, 255}));
  EXPECT_GT(DarkPixels(image, 0, 0, 800, f.top - 4), 150);
}

// The ink of a line across a cross-section of the image: its centre (the
// coverage-weighted mean position) and its total coverage (the line's width).
struct Ink {
  double centre = 0, width = 0;
};
Ink InkAlong(const Image& image, int fixed, int from, int to, bool column, int channel) {
  double sum = 0, weighted = 0;
  for (int i = from; i < to; ++i) {
    const Rgb c = column ? image.At(fixed, i) : image.At(i, fixed);
    const double coverage = (255 - c[channel]) / 255.0;  // the series' colour has 0 in `channel`
    sum += coverage;
    weighted += coverage * (i + 0.5);
  }
  return {sum > 0 ? weighted / sum : NAN, sum};
}

TEST(Plot, PngLinesPassThroughTheMappedPixels) {
  Figure figure;
  figure.width = 900;
  figure.x_min = 0, figure.x_max = 10, figure.y_min = 0, figure.y_max = 10;
  // Off the grid lines (ticks at whole numbers) so only the series inks there.
  figure.series.push_back({"", {1, 9}, {3.3, 3.3}, "#0072b2"});  // red channel 0
  figure.series.push_back({"", {7.3, 7.3}, {1, 9}, "#d55e00"});  // blue channel 0
  const Image image = DecodePng(RenderPng(figure));
  ASSERT_EQ(image.width, 900);
  const Frame f = ComputeFrame(figure);
  for (double x : {1.5, 2.5, 4.5, 6.5, 8.5}) {
    const Eigen::Vector2d p = f.ToPixel(x, 3.3);
    const Ink ink = InkAlong(image, int(p.x()), int(p.y()) - 8, int(p.y()) + 8, true, 0);
    EXPECT_NEAR(ink.centre, p.y(), 0.25) << "x = " << x;
    EXPECT_NEAR(ink.width, 2.0, 0.3) << "x = " << x;  // the line width
  }
  for (double y : {1.5, 2.5, 5.5, 8.5}) {
    const Eigen::Vector2d p = f.ToPixel(7.3, y);
    const Ink ink = InkAlong(image, int(p.y()), int(p.x()) - 8, int(p.x()) + 8, false, 2);
    EXPECT_NEAR(ink.centre, p.x(), 0.25) << "y = " << y;
    EXPECT_NEAR(ink.width, 2.0, 0.3) << "y = " << y;
  }
  // Nothing drawn past the end of a line: at x = 9.5 the row is white.
  const Eigen::Vector2d end = f.ToPixel(9.5, 3.3);
  EXPECT_EQ(image.At(int(end.x()), int(end.y())), (Rgb{255, 255, 255}));
}

TEST(Plot, LogAxesMapDecadesToEqualLengthsWithNiceTicks) {
  Figure figure;
  figure.x_log = true;
  figure.x_label = "threshold (m)";
  figure.x_min = 0.01, figure.x_max = 1, figure.y_min = 0, figure.y_max = 100;
  // Points at x <= 0 cannot be drawn: they break the line, as NaN does.
  figure.series.push_back({"", {0, 0.01, 0.1, 1, -1}, {1, 5.3, 25.3, 45.3, 90}, "#0072b2"});
  const internal::Layout layout = internal::ComputeLayout(figure);
  const Frame& f = layout.frame;
  EXPECT_NEAR(f.ToPixel(0.1, 50).x(), 0.5 * (f.left + f.right), 1e-9);
  EXPECT_NEAR(f.ToPixel(0.01, 50).x(), f.left, 1e-9);
  EXPECT_FALSE(f.ToPixel(0, 50).allFinite());
  EXPECT_FALSE(f.ToPixel(-1, 50).allFinite());
  EXPECT_EQ(layout.x_labels, (std::vector<std::string>{"0.01", "0.02", "0.05", "0.1", "0.2", "0.5", "1"}));
  EXPECT_EQ(layout.x_minor.size(), 12u);  // 0.03, 0.04, 0.06 .. 0.09, 0.3, 0.4, 0.6 .. 0.9
  // The line passes through the mapped pixels: y = 20 log10(x / 0.01) + 5.3 is straight on this axis.
  const Image image = DecodePng(RenderPng(figure));
  for (double x : {0.013, 0.15, 0.3, 0.7}) {  // off the grid lines
    const double y = 20 * std::log10(x / 0.01) + 5.3;
    const Eigen::Vector2d p = f.ToPixel(x, y);
    const Ink ink = InkAlong(image, int(p.x()), int(p.y()) - 7, int(p.y()) + 7, true, 0);
    EXPECT_NEAR(ink.centre, p.y(), 0.5) << "x = " << x;
  }
  // Many decades: labels thinned to every n-th decade, never touching.
  Figure wide;
  wide.x_log = wide.y_log = true;
  wide.series.push_back({"", {1e-9, 1e9}, {1e-3, 1e3}});
  const internal::Layout w = internal::ComputeLayout(wide);
  ASSERT_GE(w.x_ticks.size(), 3u);
  double widest = 0;
  for (const std::string& label : w.x_labels) widest = std::max(widest, internal::MeasureText(label, 13).width);
  for (size_t i = 1; i < w.x_ticks.size(); ++i)
    EXPECT_GE(w.frame.ToPixel(w.x_ticks[i], 1).x() - w.frame.ToPixel(w.x_ticks[i - 1], 1).x(), widest + 12);
  EXPECT_EQ(internal::LogTickLabel(1e-6), "1e\xE2\x88\x92" "6");
  EXPECT_EQ(internal::LogTickLabel(1e7), "1e7");
  EXPECT_NO_THROW(RenderSvg(wide));
  // Refused: limits <= 0 on a log axis, a log map.
  Figure zero = figure;
  zero.x_min = 0;
  EXPECT_THROW(RenderPng(zero), Error);
  Figure map = figure;
  map.x_min = map.y_min = 1;
  map.equal_aspect = true;
  EXPECT_THROW(ComputeFrame(map), Error);
}

TEST(Plot, PngHasTextInTheTitleAxisLabelAndTickLabelAreas) {
  Figure labelled = TwoSeries();
  Figure bare = TwoSeries();
  bare.title = bare.x_label = bare.y_label = "";
  for (Series& s : bare.series) s.label = "";
  const internal::TextSize digits = internal::MeasureText("0", internal::kTickFont);
  for (const Figure* figure : {&labelled, &bare}) {
    const bool has_text = figure == &labelled;
    const internal::Layout layout = internal::ComputeLayout(*figure);
    const Frame& f = layout.frame;
    const Image image = DecodePng(RenderPng(*figure));
    double widest = 0;
    for (const std::string& label : layout.y_labels)
      widest = std::max(widest, internal::MeasureText(label, internal::kTickFont).width);
    const int below_ticks = static_cast<int>(f.bottom + internal::kTickLength + 4 + digits.digit_height + 3);
    const int left_of_ticks = static_cast<int>(f.left - internal::kTickLength - 4 - widest - 2);
    const int title = DarkPixels(image, 0, 0, figure->width, f.top - 6);
    const int x_label = DarkPixels(image, f.left, below_ticks, f.right, figure->height);
    const int y_label = DarkPixels(image, 0, f.top, left_of_ticks, f.bottom);
    if (has_text) {
      EXPECT_GT(title, 150);
      EXPECT_GT(x_label, 100);
      EXPECT_GT(y_label, 60);
      // The title is centred over the plot area.
      int left_ink = figure->width, right_ink = 0;
      for (int y = 0; y < f.top - 6; ++y)
        for (int x = 0; x < figure->width; ++x)
          if (Dark(image.At(x, y))) left_ink = std::min(left_ink, x), right_ink = std::max(right_ink, x);
      EXPECT_NEAR(0.5 * (left_ink + right_ink), 0.5 * (f.left + f.right), 3);
    } else {
      EXPECT_EQ(title, 0);
      EXPECT_EQ(x_label, 0);
      EXPECT_EQ(y_label, 0);
    }
    // Tick labels under every x tick and left of every y tick.
    for (double x : layout.x_ticks) {
      const int u = static_cast<int>(f.ToPixel(x, f.y_min).x());
      EXPECT_GT(DarkPixels(image, u - 16, f.bottom + 6, u + 16, below_ticks), 8) << "x tick " << x;
    }
    for (double y : layout.y_ticks) {
      const int v = static_cast<int>(f.ToPixel(f.x_min, y).y());
      EXPECT_GT(DarkPixels(image, left_of_ticks, v - 7, f.left - 6, v + 7), 5) << "y tick " << y;
    }
  }
}

TEST(Plot, LegendShowsEverySampleWhereItHidesNoData) {
  const Figure figure = TwoSeries();
  const internal::Layout layout = internal::ComputeLayout(figure);
  ASSERT_EQ(layout.legend.size(), 2u);
  const int x0 = int(layout.legend_x), y0 = int(layout.legend_y);
  const int x1 = int(layout.legend_x + layout.legend_w), y1 = int(layout.legend_y + layout.legend_h);
  const Image image = DecodePng(RenderPng(figure));
  int sift = 0, green = 0, border = 0;
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      sift += Near(image.At(x, y), Hex(PaletteColor(0)), 30);
      green += Near(image.At(x, y), {0, 255, 0}, 30);
      border += Near(image.At(x, y), {204, 204, 204}, 12);
    }
  EXPECT_GT(sift, 30);   // line sample + marker
  EXPECT_GT(green, 15);  // dashed sample
  EXPECT_GT(border, 100);
  EXPECT_GT(DarkPixels(image, x0, y0, x1, y1), 40);  // "SIFT", "R2D2"
  // No point of the drawn polylines lies under the box.
  const Frame& f = layout.frame;
  for (const Series& s : figure.series)
    for (size_t k = 0; k + 1 < s.x.size(); ++k)
      for (int i = 0; i <= 50; ++i) {
        const Eigen::Vector2d p = f.ToPixel(s.x[k] + (s.x[k + 1] - s.x[k]) * i / 50.0,
                                            s.y[k] + (s.y[k + 1] - s.y[k]) * i / 50.0);
        EXPECT_FALSE(p.x() >= x0 && p.x() <= x1 && p.y() >= y0 && p.y() <= y1) << s.label << " " << k;
      }
  // Unlabelled series make no entry, labelled ones without points one.
  const internal::Layout map = internal::ComputeLayout(Map());
  ASSERT_EQ(map.legend.size(), 3u);
  EXPECT_EQ(map.legend[0].label, "seq_0");
  EXPECT_EQ(map.legend[1].label, "before optimisation");
  EXPECT_TRUE(map.legend[1].dashed);
  EXPECT_EQ(map.legend[2].label, "loop");
}

// A small DOM of an SVG, parsed by expat (a parse error fails the test).
struct Element {
  std::string name;
  std::map<std::string, std::string> attributes;
  std::string text;
  std::vector<Element*> children;
};
struct Dom {
  std::vector<std::unique_ptr<Element>> all;
  Element* root = nullptr;
  std::vector<Element*> stack;
  std::string error;
};

Dom ParseXml(const std::string& xml) {
  Dom dom;
  XML_Parser parser = XML_ParserCreate("UTF-8");
  XML_SetUserData(parser, &dom);
  XML_SetElementHandler(
      parser,
      [](void* data, const XML_Char* name, const XML_Char** attributes) {
        auto* d = static_cast<Dom*>(data);
        d->all.push_back(std::make_unique<Element>());
        Element* e = d->all.back().get();
        e->name = name;
        for (int i = 0; attributes[i]; i += 2) e->attributes[attributes[i]] = attributes[i + 1];
        if (d->stack.empty()) d->root = e;
        else d->stack.back()->children.push_back(e);
        d->stack.push_back(e);
      },
      [](void* data, const XML_Char*) { static_cast<Dom*>(data)->stack.pop_back(); });
  XML_SetCharacterDataHandler(parser, [](void* data, const XML_Char* s, int length) {
    auto* d = static_cast<Dom*>(data);
    if (!d->stack.empty()) d->stack.back()->text.append(s, length);
  });
  if (XML_Parse(parser, xml.data(), static_cast<int>(xml.size()), 1) == XML_STATUS_ERROR) {
    dom.error = std::string(XML_ErrorString(XML_GetErrorCode(parser))) + " at line " +
                std::to_string(XML_GetCurrentLineNumber(parser));
  }
  XML_ParserFree(parser);
  return dom;
}

// A style's stroke colour ("stroke:rgb(0%,44.7%,69.8%)") in 0..255, or -1s.
Rgb StrokeColor(const std::string& style) {
  const size_t at = style.find("stroke:rgb(");
  if (at == std::string::npos) return {-1, -1, -1};
  double r, g, b;
  if (std::sscanf(style.c_str() + at, "stroke:rgb(%lf%%,%lf%%,%lf%%)", &r, &g, &b) != 3) return {-1, -1, -1};
  return {int(std::lround(r * 2.55)), int(std::lround(g * 2.55)), int(std::lround(b * 2.55))};
}

// The (x, y) pairs of a path's "M x y L x y ..." data.
std::vector<Eigen::Vector2d> PathPoints(const std::string& d) {
  std::vector<Eigen::Vector2d> points;
  std::istringstream in(d);
  for (std::string token; in >> token;) {
    if (token == "M" || token == "L") {
      double x, y;
      if (in >> x >> y) points.push_back({x, y});
    }
  }
  return points;
}

std::vector<const Element*> Paths(const Dom& dom) {
  std::vector<const Element*> out;
  for (const auto& e : dom.all)
    if (e->name == "path") out.push_back(e.get());
  return out;
}

TEST(Plot, SvgIsWellFormedXmlWithTheExpectedElements) {
  Figure figure = TwoSeries();
  figure.segments.push_back({0, 0, 2, 90});
  const std::string svg = RenderSvg(figure);
  const Dom dom = ParseXml(svg);
  ASSERT_EQ(dom.error, "");
  ASSERT_NE(dom.root, nullptr);
  EXPECT_EQ(dom.root->name, "svg");
  EXPECT_EQ(dom.root->attributes.at("width"), "800px");
  EXPECT_EQ(dom.root->attributes.at("height"), "600px");
  EXPECT_EQ(dom.root->attributes.at("viewBox"), "0 0 800 600");  // scales with CSS
  ASSERT_FALSE(dom.root->children.empty());
  EXPECT_EQ(dom.root->children[0]->name, "title");
  EXPECT_EQ(dom.root->children[0]->text, "recall <vs> threshold");  // escaped in the file
  EXPECT_NE(svg.find("recall &lt;vs&gt; threshold"), std::string::npos);

  // Ids: unique, prefixed, and every reference resolves.
  std::set<std::string> ids;
  for (const auto& e : dom.all) {
    auto it = e->attributes.find("id");
    if (it == e->attributes.end()) continue;
    EXPECT_TRUE(ids.insert(it->second).second) << "duplicate id " << it->second;
    EXPECT_EQ(it->second.rfind("lf", 0), 0u) << it->second;
  }
  int references = 0;
  for (const auto& e : dom.all)
    for (const auto& [name, value] : e->attributes) {
      size_t at = value.find("url(#");
      std::string target;
      if (name == "xlink:href" && value.rfind('#', 0) == 0) target = value.substr(1);
      else if (at != std::string::npos) target = value.substr(at + 5, value.find(')', at) - at - 5);
      if (target.empty()) continue;
      ++references;
      EXPECT_TRUE(ids.count(target)) << name << "=" << value;
    }
  EXPECT_GT(references, 30);  // glyphs of the text, the clip path

  // One stroked path per series through its data points (the legend's
  // samples are other paths of the same colour), the dashed one dashed.
  const Frame f = ComputeFrame(figure);
  const std::vector<const Element*> paths = Paths(dom);
  for (size_t i = 0; i < figure.series.size(); ++i) {
    const Series& s = figure.series[i];
    int found = 0;
    for (const Element* p : paths) {
      const std::string style = p->attributes.count("style") ? p->attributes.at("style") : "";
      if (StrokeColor(style) != Hex(internal::SeriesColor(figure, i))) continue;
      const std::vector<Eigen::Vector2d> points = PathPoints(p->attributes.at("d"));
      if (points.size() != s.x.size()) continue;
      ++found;
      for (size_t k = 0; k < points.size(); ++k)
        EXPECT_LT((points[k] - f.ToPixel(s.x[k], s.y[k])).norm(), 0.01) << s.label << " point " << k;
      EXPECT_EQ(style.find("stroke-dasharray") != std::string::npos, s.dashed) << s.label;
    }
    EXPECT_EQ(found, 1) << s.label;
  }
  int segment = 0;
  for (const Element* p : paths)
    segment += StrokeColor(p->attributes.count("style") ? p->attributes.at("style") : "") == Hex("#d55e00");
  EXPECT_EQ(segment, 1);  // the segment's default colour
  // Text as glyph outlines: <symbol> glyphs used by <use>.
  int glyphs = 0, uses = 0;
  for (const auto& e : dom.all) glyphs += e->name == "symbol", uses += e->name == "use";
  EXPECT_GT(glyphs, 15);
  EXPECT_GT(uses, 40);
}

TEST(Plot, NonFinitePointsBreakTheLine) {
  Figure figure;
  figure.series.push_back({"", {0, 1, NAN, 2, 3}, {0, 1, 1, 2, 3}});
  const Dom dom = ParseXml(RenderSvg(figure));
  ASSERT_EQ(dom.error, "");
  int subpaths = -1;
  for (const Element* p : Paths(dom)) {
    if (StrokeColor(p->attributes.count("style") ? p->attributes.at("style") : "") != Hex(PaletteColor(0))) continue;
    const std::string& d = p->attributes.at("d");
    subpaths = static_cast<int>(std::count(d.begin(), d.end(), 'M'));
  }
  EXPECT_EQ(subpaths, 2);
  EXPECT_NO_THROW(RenderPng(figure));
}

TEST(Plot, PointsFarOutsideTheRangeAreClippedNotLost) {
  Figure figure;
  figure.x_min = 0, figure.x_max = 10, figure.y_min = 0, figure.y_max = 10;
  figure.series.push_back({"far", {5, 1e15}, {5.3, 5.3}, "#0072b2"});
  figure.series.push_back({"farther", {5, 5}, {2.3, -1e300}, "#d55e00", true});
  const Image image = DecodePng(RenderPng(figure));
  const Frame f = ComputeFrame(figure);
  const Eigen::Vector2d p = f.ToPixel(5, 5.3);
  // The first line runs from x = 5 to the right edge of the plot area.
  for (int u = int(p.x()) + 2; u < f.right - 1; u += 7)
    EXPECT_TRUE(Near(image.At(u, int(p.y())), Hex("#0072b2"), 40)) << u;
  EXPECT_EQ(image.At(f.right + 3, int(p.y())), (Rgb{255, 255, 255}));  // clipped at the frame
  const Eigen::Vector2d q = f.ToPixel(5, 2.3);
  for (int v = int(q.y()) + 2; v < f.bottom - 1; v += 7)
    EXPECT_TRUE(Near(image.At(int(q.x()), v), Hex("#d55e00"), 40)) << v;
  // The SVG clips them to the plot area too.
  const Dom dom = ParseXml(RenderSvg(figure));
  ASSERT_EQ(dom.error, "");
  int clips = 0;
  for (const auto& e : dom.all) clips += e->name == "clipPath";
  EXPECT_GE(clips, 1);
}

TEST(Plot, BadFiguresAreRefusedWithAClearMessage) {
  Figure bad_color = TwoSeries();
  bad_color.series[1].color = "green";
  try {
    RenderPng(bad_color);
    ADD_FAILURE() << "a bad colour was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("series 'R2D2'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'green'"), std::string::npos) << e.what();
  }
  Figure lengths = TwoSeries();
  lengths.series[0].y.pop_back();
  try {
    RenderSvg(lengths);
    ADD_FAILURE() << "x and y of different lengths were accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("x has 4 values, y has 3"), std::string::npos) << e.what();
  }
  Figure infinite = TwoSeries();
  infinite.x_max = INFINITY;
  EXPECT_THROW(RenderPng(infinite), Error);
  Figure tiny = TwoSeries();
  tiny.width = 10;
  EXPECT_THROW(RenderPng(tiny), Error);
  EXPECT_THROW(RenderSvg(tiny), Error);
  // Text that is not UTF-8 is drawn with replacement characters, not refused
  // (Cairo would stop drawing at it; XML would be ill-formed).
  Figure text = TwoSeries();
  text.title = "bad \xff\xfe bytes \x01";
  text.series[0].label = "\xc3";
  const Dom dom = ParseXml(RenderSvg(text));
  ASSERT_EQ(dom.error, "");
  EXPECT_EQ(dom.root->children[0]->text, "bad \xEF\xBF\xBD\xEF\xBF\xBD bytes  ");
  EXPECT_GT(DarkPixels(DecodePng(RenderPng(text)), 0, 0, 800, 30), 100);
}

TEST(Plot, ColoursWithAlphaBlendWithTheBackground) {
  EXPECT_NEAR(internal::ParseColor("#ff000080", "t").a, 128 / 255.0, 1e-12);
  Figure figure;
  figure.x_min = 0, figure.x_max = 10, figure.y_min = 0, figure.y_max = 10;
  figure.series.push_back({"", {5.5}, {5.3}, "#00000080", true, false, false});  // one dot
  const Image image = DecodePng(RenderPng(figure));
  const Eigen::Vector2d p = ComputeFrame(figure).ToPixel(5.5, 5.3);
  EXPECT_TRUE(Near(image.At(int(p.x()), int(p.y())), {127, 127, 127}, 3));  // half black on white
}

TEST(Plot, SameFigureSameBytesDifferentFiguresDifferentIds) {
  const std::vector<uint8_t> png = RenderPng(Map());
  const std::string svg = RenderSvg(Map());
  for (int i = 0; i < 3; ++i) RenderSvg(TwoSeries());  // moves Cairo's global counters
  EXPECT_EQ(RenderPng(Map()), png);
  EXPECT_EQ(RenderSvg(Map()), svg);
  // Two figures inlined in one HTML page share no id.
  auto id_set = [](const std::string& s) {
    std::set<std::string> ids;
    const Dom dom = ParseXml(s);
    for (const auto& e : dom.all)
      if (e->attributes.count("id")) ids.insert(e->attributes.at("id"));
    return ids;
  };
  const std::set<std::string> a = id_set(svg), b = id_set(RenderSvg(TwoSeries()));
  EXPECT_FALSE(a.empty());
  for (const std::string& id : b) EXPECT_EQ(a.count(id), 0u) << id;
}

TEST(Plot, RendersTheSameFromSeveralThreadsAtOnce) {
  // Stages with threads may draw concurrently: one font face serves them all.
  const std::vector<uint8_t> png = RenderPng(Map());
  const std::string svg = RenderSvg(Map());
  std::vector<std::vector<uint8_t>> pngs(4);
  std::vector<std::string> svgs(4);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      pngs[t] = RenderPng(Map());
      svgs[t] = RenderSvg(Map());
    });
  for (std::thread& t : threads) t.join();
  for (int t = 0; t < 4; ++t) {
    EXPECT_EQ(pngs[t], png) << t;
    EXPECT_EQ(svgs[t], svg) << t;
  }
}

// Runs in two roles: the test spawns this executable again with
// LOCFORGE_PLOT_DUMP set, and that child writes the files to compare.
TEST(Plot, SameBytesInAnotherProcess) {
  if (const char* dump = std::getenv("LOCFORGE_PLOT_DUMP")) {
    WriteFigure(Map(), std::string(dump) + ".png");
    WriteFigure(Map(), std::string(dump) + ".svg");
    return;
  }
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("locforge_plot_process_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string stem = (dir / "map").string();
  std::vector<std::string> env_strings = {"LOCFORGE_PLOT_DUMP=" + stem};
  for (char** e = environ; *e; ++e)
    if (std::strncmp(*e, "LOCFORGE_PLOT_DUMP=", 19) != 0) env_strings.push_back(*e);
  std::vector<char*> env;
  for (std::string& s : env_strings) env.push_back(s.data());
  env.push_back(nullptr);
  std::string self = std::filesystem::read_symlink("/proc/self/exe").string();
  std::string filter = "--gtest_filter=Plot.SameBytesInAnotherProcess";
  char* argv[] = {self.data(), filter.data(), nullptr};
  pid_t pid = 0;
  ASSERT_EQ(posix_spawn(&pid, self.c_str(), nullptr, nullptr, argv, env.data()), 0);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  auto read = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), {});
  };
  const std::vector<uint8_t> png = RenderPng(Map());
  EXPECT_EQ(read(stem + ".png"), std::string(png.begin(), png.end()));
  EXPECT_EQ(read(stem + ".svg"), RenderSvg(Map()));
  std::filesystem::remove_all(dir);
}

TEST(Plot, WriteFigureByExtensionAndRefusesOthers) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("locforge_plot_test_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  WriteFigure(TwoSeries(), (dir / "a.png").string());
  WriteFigure(TwoSeries(), (dir / "a.svg").string());
  std::ifstream png(dir / "a.png", std::ios::binary);
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(png)), {});
  EXPECT_EQ(DecodePng(bytes).width, 800);
  EXPECT_GT(std::filesystem::file_size(dir / "a.svg"), 1000u);
  EXPECT_THROW(WriteFigure(TwoSeries(), (dir / "a.jpg").string()), Error);
  std::filesystem::remove_all(dir);
}

TEST(Plot, TextCleaningAndSegmentClipping) {
  EXPECT_EQ(internal::CleanText("caf\xc3\xa9 \xe2\x88\x92" "1"), "caf\xc3\xa9 \xe2\x88\x92" "1");
  EXPECT_EQ(internal::CleanText("a\xc0\xafz"), "a\xEF\xBF\xBD\xEF\xBF\xBDz");  // overlong '/'
  EXPECT_EQ(internal::CleanText("\xed\xa0\x80"), "\xEF\xBF\xBD\xEF\xBF\xBD\xEF\xBF\xBD");  // surrogate
  Eigen::Vector2d a(-10, 5), b(20, 5);
  ASSERT_TRUE(internal::ClipSegment(&a, &b, 0, 0, 10, 10));
  EXPECT_EQ(a, Eigen::Vector2d(0, 5));
  EXPECT_EQ(b, Eigen::Vector2d(10, 5));
  Eigen::Vector2d c(-10, -5), d(-1, 20);
  EXPECT_FALSE(internal::ClipSegment(&c, &d, 0, 0, 10, 10));
}

}  // namespace
}  // namespace locforge::plot

#include "locforge/plot.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "layout.h"
#include "locforge/error.h"

namespace locforge::plot {
namespace {

uint32_t ReadU32(const std::vector<uint8_t>& b, size_t at) {
  return uint32_t(b[at]) << 24 | uint32_t(b[at + 1]) << 16 | uint32_t(b[at + 2]) << 8 | b[at + 3];
}

// Decodes the PNGs RenderPng writes (one IDAT, filter 0) back to RGB and
// checks every chunk's CRC on the way.
struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;
  std::array<uint8_t, 3> At(int x, int y) const {
    const size_t i = 3 * (size_t(y) * width + x);
    return {rgb[i], rgb[i + 1], rgb[i + 2]};
  }
};

Image DecodePng(const std::vector<uint8_t>& png) {
  Image image;
  EXPECT_EQ(std::vector<uint8_t>(png.begin(), png.begin() + 8),
            (std::vector<uint8_t>{0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'}));
  std::vector<uint8_t> packed;
  for (size_t at = 8; at + 12 <= png.size();) {
    const uint32_t length = ReadU32(png, at);
    const std::string type(png.begin() + at + 4, png.begin() + at + 8);
    const uint32_t crc = ReadU32(png, at + 8 + length);
    EXPECT_EQ(crc, crc32(0L, png.data() + at + 4, length + 4)) << type;
    if (type == "IHDR") {
      image.width = static_cast<int>(ReadU32(png, at + 8));
      image.height = static_cast<int>(ReadU32(png, at + 12));
      EXPECT_EQ(png[at + 16], 8);
      EXPECT_EQ(png[at + 17], 2);
    } else if (type == "IDAT") {
      packed.insert(packed.end(), png.begin() + at + 8, png.begin() + at + 8 + length);
    }
    at += 12 + length;
  }
  std::vector<uint8_t> raw((3 * size_t(image.width) + 1) * image.height);
  uLongf raw_size = raw.size();
  EXPECT_EQ(uncompress(raw.data(), &raw_size, packed.data(), packed.size()), Z_OK);
  EXPECT_EQ(raw_size, raw.size());
  for (int y = 0; y < image.height; ++y) {
    const uint8_t* line = raw.data() + y * (3 * size_t(image.width) + 1);
    EXPECT_EQ(line[0], 0);
    image.rgb.insert(image.rgb.end(), line + 1, line + 1 + 3 * image.width);
  }
  return image;
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

TEST(Plot, TicksAreNiceAndCoverTheRange) {
  const std::vector<double> ticks = internal::Ticks(0, 1, 5);
  ASSERT_EQ(ticks.size(), 6u);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(ticks[i], 0.2 * i, 1e-12);
  // (12.2 + 3.7) / 6 = 2.65 -> the next nice step is 5.
  EXPECT_EQ(internal::Ticks(-3.7, 12.2, 6), (std::vector<double>{0, 5, 10}));
  EXPECT_EQ(internal::Ticks(-13.7, 12.2, 6), (std::vector<double>{-10, -5, 0, 5, 10}));
  EXPECT_EQ(internal::TickLabel(0.25, 0.05), "0.25");
  EXPECT_EQ(internal::TickLabel(250, 50), "250");
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
}

TEST(Plot, PngShowsEachSeriesAtItsDataPoints) {
  const Figure figure = TwoSeries();
  const Image image = DecodePng(RenderPng(figure));
  ASSERT_EQ(image.width, 800);
  ASSERT_EQ(image.height, 600);
  const Frame f = ComputeFrame(figure);
  const auto sift = internal::ParseColor(PaletteColor(0));
  for (size_t k = 1; k < 4; ++k) {  // k = 0 is under the other series' first point
    const Eigen::Vector2d p = f.ToPixel(figure.series[0].x[k], figure.series[0].y[k]);
    EXPECT_EQ(image.At(int(p.x()), int(p.y())), sift) << "point " << k;
  }
  // The dashed green series: most of the samples along its first segment are green.
  const Eigen::Vector2d a = f.ToPixel(0, 0), b = f.ToPixel(0.5, 50);
  int green = 0;
  for (int i = 0; i <= 100; ++i) {
    const Eigen::Vector2d p = a + (b - a) * (i / 100.0);
    green += image.At(int(p.x()), int(p.y())) == std::array<uint8_t, 3>{0, 255, 0};
  }
  EXPECT_GT(green, 40);
  EXPECT_LT(green, 90);  // dashed: gaps
  // Background stays white away from the data; text is drawn (black pixels in the title band).
  EXPECT_EQ(image.At(f.right - 5, f.bottom - 5), (std::array<uint8_t, 3>{255, 255, 255}));
  int black = 0;
  for (int y = 5; y < 30; ++y)
    for (int x = 0; x < 800; ++x) black += image.At(x, y) == std::array<uint8_t, 3>{0, 0, 0};
  EXPECT_GT(black, 200);
}

TEST(Plot, SvgHasOnePolylinePerSeriesAndEscapesText) {
  Figure figure = TwoSeries();
  figure.segments.push_back({0, 0, 2, 90});
  const std::string svg = RenderSvg(figure);
  size_t polylines = 0;
  for (size_t at = svg.find("<polyline"); at != std::string::npos; at = svg.find("<polyline", at + 1))
    ++polylines;
  EXPECT_EQ(polylines, 2u);
  EXPECT_NE(svg.find("recall &lt;vs&gt; threshold"), std::string::npos);
  EXPECT_NE(svg.find("stroke-dasharray"), std::string::npos);
  EXPECT_NE(svg.find("#d62728"), std::string::npos);  // the segment's default colour
}

TEST(Plot, NonFinitePointsBreakTheLine) {
  Figure figure;
  figure.series.push_back({"", {0, 1, NAN, 2, 3}, {0, 1, 1, 2, 3}});
  const std::string svg = RenderSvg(figure);
  EXPECT_NE(svg.find("<polyline"), svg.rfind("<polyline"));
  EXPECT_NO_THROW(RenderPng(figure));
}

TEST(Plot, WriteFigureByExtensionAndRefusesOthers) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "locforge_plot_test";
  std::filesystem::create_directories(dir);
  WriteFigure(TwoSeries(), (dir / "a.png").string());
  WriteFigure(TwoSeries(), (dir / "a.svg").string());
  std::ifstream png(dir / "a.png", std::ios::binary);
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(png)), {});
  EXPECT_EQ(DecodePng(bytes).width, 800);
  EXPECT_GT(std::filesystem::file_size(dir / "a.svg"), 1000u);
  EXPECT_THROW(WriteFigure(TwoSeries(), (dir / "a.jpg").string()), Error);
  Figure tiny = TwoSeries();
  tiny.width = 10;
  EXPECT_THROW(RenderPng(tiny), Error);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace locforge::plot

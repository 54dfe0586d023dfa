#include "image_content.h"
#include "testing_queries.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <cmath>

#include "locforge/error.h"

namespace locforge::analysis {
namespace {

using evaluation::QueryError;

// A periodic image: 128 + sum of A_k sin(2 pi f_k x / w + phase_k) (x
// frequencies in cycles per image width, so each term is exactly periodic).
cv::Mat Sinusoids(int w, int h, const std::vector<std::pair<double, double>>& amplitude_frequency, bool vertical = false) {
  cv::Mat image(h, w, CV_64F);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double v = 128;
      for (const auto& [a, f] : amplitude_frequency)
        v += a * std::sin(2 * M_PI * f * (vertical ? static_cast<double>(y) / h : static_cast<double>(x) / w) + 0.3);
      image.at<double>(y, x) = v;
    }
  return image;
}

TEST(LowFrequencyScore, FlatImageScoresZero) {
  EXPECT_NEAR(LowFrequencyScore(cv::Mat(64, 80, CV_8U, cv::Scalar(200))), 0.0, 1e-9);
}

TEST(LowFrequencyScore, SinusoidAboveTheCutoffScoresTwoAOverPi) {
  // Mean |A sin| = 2A / pi: the whole sinusoid is the high-frequency part.
  const double a = 30;
  const double score = LowFrequencyScore(Sinusoids(256, 192, {{a, 100}}));
  EXPECT_NEAR(score, 2 * a / M_PI, 0.01 * a);
}

TEST(LowFrequencyScore, SinusoidBelowTheCutoffScoresZero) {
  EXPECT_NEAR(LowFrequencyScore(Sinusoids(256, 192, {{50, 20}})), 0.0, 1e-6);
}

TEST(LowFrequencyScore, OnlyTheHighPartCounts) {
  // A strong low frequency (removed) plus a weak high one (kept).
  const double score = LowFrequencyScore(Sinusoids(256, 192, {{60, 10}, {12, 90}}));
  EXPECT_NEAR(score, 2 * 12 / M_PI, 0.2);
}

TEST(LowFrequencyScore, CutoffInCyclesPerWidthOnBothAxes) {
  // A vertical sinusoid of 50 cycles over a height of 96 px is 50 * 256 / 96
  // = 133 cycles per image width: above the cutoff of 60 ...
  EXPECT_NEAR(LowFrequencyScore(Sinusoids(256, 96, {{20, 50}}, true)), 2 * 20 / M_PI, 0.3);
  // ... and below a cutoff of 140.
  LowFrequencyOptions o;
  o.cutoff_cycles_per_width = 140;
  EXPECT_NEAR(LowFrequencyScore(Sinusoids(256, 96, {{20, 50}}, true), o), 0.0, 1e-6);
}

TEST(LowFrequencyScore, SameSceneSameScoreAtHalfResolution) {
  // The cutoff follows the image width: a downscaled copy keeps its score
  // (up to the resampling filter's attenuation, 3 % at 40 cycles per width
  // of 256 px for a 2x2 box).
  LowFrequencyOptions o;
  o.cutoff_cycles_per_width = 20;
  const cv::Mat full = Sinusoids(512, 384, {{40, 8}, {25, 40}});
  cv::Mat half;
  cv::resize(full, half, cv::Size(256, 192), 0, 0, cv::INTER_AREA);
  EXPECT_NEAR(LowFrequencyScore(full, o), 2 * 25 / M_PI, 0.2);
  EXPECT_NEAR(LowFrequencyScore(full, o), LowFrequencyScore(half, o), 0.05 * LowFrequencyScore(full, o));
}

TEST(LowFrequencyScore, RefusesColourAndEmptyImages) {
  EXPECT_THROW(LowFrequencyScore(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(LowFrequencyScore(cv::Mat(8, 8, CV_8UC3)), std::invalid_argument);
}

TEST(Crowdedness, CountsMaskPixels) {
  cv::Mat mask(100, 200, CV_8U, cv::Scalar(0));
  mask(cv::Rect(10, 20, 50, 40)).setTo(255);  // 2000 of 20000 pixels
  EXPECT_DOUBLE_EQ(CrowdednessPercent(mask), 10.0);
  mask(cv::Rect(100, 0, 10, 10)).setTo(100);  // <= 127: not a person
  EXPECT_DOUBLE_EQ(CrowdednessPercent(mask), 10.0);
  EXPECT_THROW(CrowdednessPercent(cv::Mat(4, 4, CV_32F)), std::invalid_argument);
}

using testing::Q;

TEST(Tables, SplitByContentWithCounts) {
  // a, b: low-frequency (score < 20); c, d: other. a and c within 0.1 m / 1 deg.
  const std::vector<ImageContent> content = {Classify("a", 5, 30, {}), Classify("b", 19.9, 0, {}),
                                             Classify("c", 20, 50, {}), Classify("d", 40, 19.9, {})};
  const std::vector<MethodErrors> methods = {
      {"m", {Q("a", true, 0.05, 0.5), Q("b", false, 0, 0), Q("c", true, 0.01, 0.1), Q("d", true, 0.2, 1.5)}}};
  const std::vector<evaluation::Threshold> t = {{0.1, 1}, {0.25, 2}, {1, 5}};
  const auto lf = LowFrequencyTable(methods, content, t);
  EXPECT_EQ(lf.header[1], "low-frequency (n=2)");
  EXPECT_EQ(lf.header[2], "other (n=2)");
  EXPECT_EQ(lf.rows[0][1], "50.0 / 50.0 / 50.0");
  EXPECT_EQ(lf.rows[0][2], "50.0 / 100.0 / 100.0");
  const auto crowd = CrowdednessTable(methods, content, t);
  EXPECT_EQ(crowd.header[1], "crowded (n=2)");  // a (30 %), c (50 %); d at 19.9 % is not
  EXPECT_EQ(crowd.rows[0][1], "100.0 / 100.0 / 100.0");
  EXPECT_EQ(crowd.rows[0][2], "0.0 / 50.0 / 50.0");
}

TEST(Tables, RefuseAQueryWithoutContent) {
  const std::vector<MethodErrors> methods = {{"m", {Q("a", true, 0, 0), Q("zz", true, 0, 0)}}};
  EXPECT_THROW(LowFrequencyTable(methods, {Classify("a", 5, 1, {})}, {{0.1, 1}}), InputError);
  // Crowdedness without masks is refused, not counted as 0 %.
  EXPECT_THROW(CrowdednessTable({{"m", {Q("a", true, 0, 0)}}}, {Classify("a", 5, -1, {})}, {{0.1, 1}}), InputError);
}

TEST(PerQuery, ParsesAndRefusesMalformedRows) {
  evaluation::Table t;
  t.header = {"image", "device_id", "group", "split", "localized", "position_error_m", "rotation_error_deg"};
  t.rows = {{"q1.jpg", "cam", "all", "all", "1", "0.5", "2"}, {"q2.jpg", "cam", "all", "all", "0", "", ""}};
  const auto e = ParsePerQuery(t, "per_query.csv");
  ASSERT_EQ(e.size(), 2u);
  EXPECT_TRUE(e[0].localized);
  EXPECT_DOUBLE_EQ(e[0].position_m, 0.5);
  EXPECT_FALSE(e[1].localized);
  t.rows[0][5] = "0.5m";
  try {
    ParsePerQuery(t, "per_query.csv");
    FAIL() << "accepted a malformed number";
  } catch (const InputError& err) {
    EXPECT_NE(std::string(err.what()).find("per_query.csv"), std::string::npos);
    EXPECT_NE(std::string(err.what()).find(":2"), std::string::npos) << err.what();
  }
}

TEST(Content, ParsesAndRefusesMalformedRows) {
  evaluation::Table t;
  t.header = {"image", "device_id", "low_frequency_score", "low_frequency", "crowdedness_percent", "crowded"};
  t.rows = {{"a.jpg", "cam", "4.5", "1", "", ""}, {"b.jpg", "cam", "30", "0", "25", "1"}};
  const auto c = ParseContent(t, "content.csv");
  ASSERT_EQ(c.size(), 2u);
  EXPECT_TRUE(c[0].low_frequency);
  EXPECT_LT(c[0].crowdedness_percent, 0);  // no mask
  EXPECT_TRUE(c[1].crowded);
  EXPECT_DOUBLE_EQ(c[1].crowdedness_percent, 25);
  for (const auto& [column, bad] : std::vector<std::pair<size_t, std::string>>{{4, "25%"}, {5, "yes"}, {2, ""}}) {
    evaluation::Table broken = t;
    broken.rows[1][column] = bad;
    try {
      ParseContent(broken, "content.csv");
      FAIL() << "accepted '" << bad << "' in column " << t.header[column];
    } catch (const InputError& err) {
      EXPECT_NE(std::string(err.what()).find("content.csv:3"), std::string::npos) << err.what();
      EXPECT_NE(std::string(err.what()).find(t.header[column]), std::string::npos) << err.what();
    }
  }
}

TEST(Ranking, LocalizedFirstThenErrorsThenName) {
  const auto r = RankedBestFirst({Q("z", false, 0, 0), Q("b", true, 0.2, 1), Q("a", true, 0.2, 1), Q("c", true, 0.01, 9),
                                  Q("y", false, 0, 0)});
  std::string order;
  for (const auto& e : r) order += e.image;
  EXPECT_EQ(order, "cabyz");
}

}  // namespace
}  // namespace locforge::analysis

// The report's number formatting: known inputs, exact strings.
#include "report_html.h"

#include <gtest/gtest.h>

namespace locforge::host::report {
namespace {

TEST(ReportFormat, LengthsInMillimetresCentimetresOrMetres) {
  EXPECT_EQ(FormatLength(0.009493086541305196), "9.49 mm");
  EXPECT_EQ(FormatLength(0.00207), "2.07 mm");
  EXPECT_EQ(FormatLength(0.0004), "0.40 mm");
  EXPECT_EQ(FormatLength(0), "0.00 mm");
  EXPECT_EQ(FormatLength(0.009996), "1.00 cm");  // rounds up out of mm
  EXPECT_EQ(FormatLength(0.0342), "3.42 cm");
  EXPECT_EQ(FormatLength(0.1), "10.0 cm");
  EXPECT_EQ(FormatLength(0.949), "94.9 cm");
  EXPECT_EQ(FormatLength(0.99971), "1.00 m");
  EXPECT_EQ(FormatLength(1.25), "1.25 m");
  EXPECT_EQ(FormatLength(123.456), "123.46 m");
  EXPECT_EQ(FormatLength(-0.0021), "-2.10 mm");
}

TEST(ReportFormat, DegreesWithThreeSignificantDigits) {
  EXPECT_EQ(FormatDegrees(0.0325), "0.0325\xc2\xb0");
  EXPECT_EQ(FormatDegrees(0.03451234), "0.0345\xc2\xb0");
  EXPECT_EQ(FormatDegrees(1.23456), "1.23\xc2\xb0");
  EXPECT_EQ(FormatDegrees(12.345), "12.3\xc2\xb0");
  EXPECT_EQ(FormatDegrees(123.45), "123\xc2\xb0");
  EXPECT_EQ(FormatDegrees(9.996), "10.0\xc2\xb0");
  EXPECT_EQ(FormatDegrees(0), "0\xc2\xb0");
}

TEST(ReportFormat, RecallAndPercent) {
  EXPECT_EQ(FormatRecall(98.6842), "98.7 %");
  EXPECT_EQ(FormatRecall(100), "100.0 %");
  EXPECT_EQ(FormatPercent(0.012345), "0.0123 %");
  EXPECT_EQ(FormatPercent(3), "3.00 %");
}

TEST(ReportFormat, DurationsInSecondsMinutesOrHours) {
  EXPECT_EQ(FormatDuration(12.46), "12.5 s");
  EXPECT_EQ(FormatDuration(192), "3.2 min");
  EXPECT_EQ(FormatDuration(172804.0), "48.0 h");
}

TEST(ReportFormat, ColumnUnitsFromHeaders) {
  EXPECT_EQ(UnitOf("median_position_m"), Unit::kMetres);
  EXPECT_EQ(UnitOf("rpe_1m_m"), Unit::kMetres);
  EXPECT_EQ(UnitOf("position RMS (cm)"), Unit::kCentimetres);
  EXPECT_EQ(UnitOf("rotation RMS (deg)"), Unit::kDegrees);
  EXPECT_EQ(UnitOf("rpe_1m_deg"), Unit::kDegrees);
  EXPECT_EQ(UnitOf("focal error RMS (%)"), Unit::kPercent);
  EXPECT_EQ(UnitOf("0.25m,2deg"), Unit::kRecall);
  EXPECT_EQ(UnitOf("(0.1m, 1deg)"), Unit::kRecall);
  EXPECT_EQ(UnitOf("time offset (ms)"), Unit::kNone);
  EXPECT_EQ(UnitOf("reproj before (px)"), Unit::kNone);
  EXPECT_EQ(UnitOf("queries"), Unit::kNone);
}

TEST(ReportFormat, CellsAsShown) {
  EXPECT_EQ(DisplayCell("0.009493086541305196", Unit::kMetres), "9.49 mm");
  EXPECT_EQ(DisplayCell("0.35", Unit::kCentimetres), "3.50 mm");
  EXPECT_EQ(DisplayCell("0.0325", Unit::kDegrees), "0.0325\xc2\xb0");
  EXPECT_EQ(DisplayCell("100.0 / 98.7 / 100", Unit::kRecall), "100.0 / 98.7 / 100.0 %");
  EXPECT_EQ(DisplayCell("-", Unit::kRecall), "-");
  EXPECT_EQ(DisplayCell("map_01", Unit::kMetres), "map_01");
  EXPECT_EQ(DisplayCell("152", Unit::kNone), "152");
  EXPECT_EQ(DisplayCell("0.125", Unit::kNone), "0.125");
  EXPECT_EQ(DisplayCell("1.000123456", Unit::kNone), "1.000");
  EXPECT_EQ(DisplayCell("0.009493086541305196", Unit::kNone), "0.009493");
  EXPECT_EQ(DisplayCell("12345.678", Unit::kNone), "12346");
  EXPECT_EQ(DisplayCell("1.2345678e-07", Unit::kNone), "1.23e-07");
}

TEST(ReportFormat, LongNumbersInTextShortened) {
  EXPECT_EQ(ShortenNumbers("ATE 0.009493086541305196 m, plugin 0.12.0, 1.5 s, v2.3456789x"),
            "ATE 0.009493 m, plugin 0.12.0, 1.5 s, v2.3456789x");
}

TEST(ReportFormat, TableCellsKeepValuesAndUnits) {
  Csv csv;
  csv.header = {"metric", "count", "rmse", "median_position_m"};
  csv.rows = {{"ape_rotation_deg", "10", "0.03451234", "0.00207"}};
  const std::string html = Table(csv, "nodes/x/metrics.csv", "");
  EXPECT_NE(html.find("<td class=\"num\" data-value=\"10\">10</td>"), std::string::npos) << html;
  EXPECT_NE(html.find("data-value=\"0.03451234\" data-unit=\"deg\">0.0345\xc2\xb0</td>"), std::string::npos)
      << html;
  EXPECT_NE(html.find("data-value=\"0.00207\" data-unit=\"m\">2.07 mm</td>"), std::string::npos) << html;
}

}  // namespace
}  // namespace locforge::host::report

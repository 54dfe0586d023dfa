// Pieces of the self-contained HTML report (cmd_report.cc): escaping, data
// URIs, CSV files as tables whose cells keep the file's exact values, and the
// graph drawn as an SVG. No script, no network: one file that opens anywhere
// and prints.
#ifndef LOCFORGE_HOST_REPORT_HTML_H_
#define LOCFORGE_HOST_REPORT_HTML_H_

#include <filesystem>
#include <string>
#include <vector>

#include "run_record.h"

namespace locforge::host::report {

namespace fs = std::filesystem;

std::string Escape(const std::string& text);  // HTML text and attribute values
std::string Base64(const std::string& bytes);
// <img> of an SVG or PNG file as a data URI; "" when the file is absent.
std::string Image(const fs::path& file, const std::string& alt, const std::string& css_class = "");

// A CSV file: '#' lines are comments (kept apart), the first other line the
// header. Quoted fields with commas are read as one.
struct Csv {
  fs::path file;
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::vector<std::string> comments;
  int Column(const std::string& name) const;  // -1 when absent
  const std::string& Cell(size_t row, const std::string& column) const;  // "" when absent
};
// Throws InputError naming the file and line on a row with the wrong count.
Csv ReadCsv(const fs::path& file);

// What a column's numbers measure, read from its header: "_m", "(m)" metres,
// "(cm)", "(mm)", "_deg", "(deg)" degrees, "(%)", "_percent" percent, and
// recall at a threshold pair ("0.25m,2deg") or named "recall" (in %).
enum class Unit { kNone, kMetres, kCentimetres, kMillimetres, kDegrees, kPercent, kRecall };
Unit UnitOf(const std::string& header);
// "m", "cm", "mm", "deg", "%", "recall", "": the cell's data-unit attribute.
const char* UnitName(Unit unit);

// Numbers as a paper's table shows them:
// lengths in mm below 1 cm (2 decimals), in cm below 1 m (2 decimals below
// 10 cm, else 1), else in m (2 decimals): "2.07 mm", "3.42 cm", "1.25 m";
std::string FormatLength(double metres);
// degrees with 3 significant digits: "0.0325°", "1.23°", "123°";
std::string FormatDegrees(double degrees);
// recall with one decimal: "98.7 %"; other percentages with 3 significant
// digits: "0.0123 %";
std::string FormatRecall(double percent);
std::string FormatPercent(double percent);
// numbers without a unit: integers and values of at most 5 significant
// digits as written, others with 4 significant digits, never an exponent
// between 1e-4 and 1e15.
std::string FormatPlain(const std::string& written, double value);
// a duration in the unit a person reads it in: "12.5 s", "3.2 min", "48.0 h";
std::string FormatDuration(double seconds);
// `value` rounded to `digits` significant digits in fixed notation.
std::string Significant(double value, int digits);

// The text a person reads for a CSV value of a column of `unit`: a number
// formatted as above, each number of "a / b / c" likewise (the unit said
// once), anything else as written.
std::string DisplayCell(const std::string& value, Unit unit);
// Free text (log lines, Markdown) with every decimal number of more than 6
// significant digits shortened to 4.
std::string ShortenNumbers(const std::string& text);

// <table class="data" data-source="SOURCE">: every cell holds its exact value
// in data-value, the unit of that value in data-unit, and the formatted one
// as text. A column's unit comes from its header, else `fallback`; the
// statistics columns (rmse, mean, median, std, min, max) of a row labelled
// with a unit (e.g. "ape_rotation_deg") take that unit.
std::string Table(const Csv& csv, const std::string& source, const std::string& caption,
                  const std::vector<std::string>& columns = {}, Unit fallback = Unit::kNone);

// The graph: nodes in layers by depth (top to bottom), wires as curves,
// boxes coloured by status. An SVG document.
std::string GraphSvg(const std::vector<RunRecord::Node>& nodes);

}  // namespace locforge::host::report

#endif  // LOCFORGE_HOST_REPORT_HTML_H_

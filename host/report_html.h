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

// The text a person reads for a CSV value: numbers with more than 5
// significant digits shortened to 4, everything else as written.
std::string DisplayNumber(const std::string& value);
// <table class="data" data-source="SOURCE">: every cell holds its exact value
// in data-value and the shortened one as text.
std::string Table(const Csv& csv, const std::string& source, const std::string& caption,
                  const std::vector<std::string>& columns = {});

// The graph: nodes in layers by depth (top to bottom), wires as curves,
// boxes coloured by status. An SVG document.
std::string GraphSvg(const std::vector<RunRecord::Node>& nodes);

}  // namespace locforge::host::report

#endif  // LOCFORGE_HOST_REPORT_HTML_H_

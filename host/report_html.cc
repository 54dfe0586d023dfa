#include "report_html.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <regex>
#include <set>

#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/params.h"

namespace locforge::host::report {

std::string Escape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string Base64(const std::string& bytes) {
  static const char kTable[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const uint32_t v = (static_cast<unsigned char>(bytes[i]) << 16) | (static_cast<unsigned char>(bytes[i + 1]) << 8) |
                       static_cast<unsigned char>(bytes[i + 2]);
    out += kTable[v >> 18], out += kTable[(v >> 12) & 63], out += kTable[(v >> 6) & 63], out += kTable[v & 63];
  }
  if (i < bytes.size()) {
    uint32_t v = static_cast<unsigned char>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= static_cast<unsigned char>(bytes[i + 1]) << 8;
    out += kTable[v >> 18], out += kTable[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? kTable[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

std::string Image(const fs::path& file, const std::string& alt, const std::string& css_class) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return "";
  const std::string ext = file.extension().string();
  const std::string mime = ext == ".svg" ? "image/svg+xml" : ext == ".png" ? "image/png" : "";
  if (mime.empty()) return "";
  return "<img src=\"data:" + mime + ";base64," + Base64(ReadFile(file)) + "\" alt=\"" + Escape(alt) + "\"" +
         (css_class.empty() ? "" : " class=\"" + css_class + "\"") + ">";
}

namespace {

std::vector<std::string> SplitQuoted(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        out.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        out.back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.emplace_back();
    } else if (c != '\r') {
      out.back() += c;
    }
  }
  return out;
}

bool ParseNumber(const std::string& s, double* v) {
  if (s.empty()) return false;
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return end && *end == '\0' && std::isfinite(*v);
}

}  // namespace

int Csv::Column(const std::string& name) const {
  const auto it = std::find(header.begin(), header.end(), name);
  return it == header.end() ? -1 : static_cast<int>(it - header.begin());
}

const std::string& Csv::Cell(size_t row, const std::string& column) const {
  static const std::string kEmpty;
  const int c = Column(column);
  if (c < 0 || row >= rows.size() || c >= static_cast<int>(rows[row].size())) return kEmpty;
  return rows[row][c];
}

Csv ReadCsv(const fs::path& file) {
  Csv csv;
  csv.file = file;
  std::ifstream in(file);
  if (!in) throw InputError(file.string(), 0, "", "cannot read");
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    if (line[0] == '#') {
      csv.comments.push_back(line);
      continue;
    }
    std::vector<std::string> fields = SplitQuoted(line);
    if (csv.header.empty()) {
      csv.header = std::move(fields);
      continue;
    }
    if (fields.size() != csv.header.size())
      throw InputError(file.string(), n, "", "expected " + std::to_string(csv.header.size()) + " fields, got " +
                                                 std::to_string(fields.size()));
    csv.rows.push_back(std::move(fields));
  }
  return csv;
}

namespace {

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// Significant digits of a number as written ("0.00207" has 3).
int WrittenDigits(const std::string& value) {
  int digits = 0;
  bool leading = true;
  for (char c : value) {
    if (c == 'e' || c == 'E') break;
    if (!std::isdigit(static_cast<unsigned char>(c))) continue;
    if (leading && c == '0') continue;
    leading = false;
    ++digits;
  }
  return digits;
}

std::string Printf(const char* format, int decimals, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, decimals, v);
  return buf;
}

const char kDegreeSign[] = "\xc2\xb0";

}  // namespace

Unit UnitOf(const std::string& header) {
  const std::string h = Lower(header);
  static const std::regex threshold(R"(\s*\(?\s*[0-9.]+\s*m\s*,\s*[0-9.]+\s*deg\s*\)?\s*)");
  if (h.find("recall") != std::string::npos || std::regex_match(h, threshold)) return Unit::kRecall;
  auto unit = [&](const char* name) {
    const std::string n = name;
    return EndsWith(h, "(" + n + ")") || EndsWith(h, "_" + n) || EndsWith(h, " " + n);
  };
  if (unit("%") || EndsWith(h, "_percent") || EndsWith(h, "_pct")) return Unit::kPercent;
  if (unit("mm")) return Unit::kMillimetres;
  if (unit("cm")) return Unit::kCentimetres;
  if (unit("m")) return Unit::kMetres;
  if (unit("deg")) return Unit::kDegrees;
  return Unit::kNone;
}

const char* UnitName(Unit unit) {
  switch (unit) {
    case Unit::kMetres: return "m";
    case Unit::kCentimetres: return "cm";
    case Unit::kMillimetres: return "mm";
    case Unit::kDegrees: return "deg";
    case Unit::kPercent: return "%";
    case Unit::kRecall: return "recall";
    case Unit::kNone: break;
  }
  return "";
}

std::string Significant(double value, int digits) {
  if (!std::isfinite(value)) return value != value ? "nan" : value > 0 ? "inf" : "-inf";
  if (value == 0) return "0";
  const int exponent = static_cast<int>(std::floor(std::log10(std::fabs(value))));
  int decimals = std::clamp(digits - 1 - exponent, 0, 15);
  std::string text = Printf("%.*f", decimals, value);
  // 9.996 to 3 digits rounds up to "10.00": one decimal fewer.
  if (decimals > 0 && std::fabs(std::strtod(text.c_str(), nullptr)) >= std::pow(10.0, exponent + 1))
    text = Printf("%.*f", decimals - 1, value);
  return text;
}

std::string FormatLength(double metres) {
  if (!std::isfinite(metres)) return Significant(metres, 3);
  const double a = std::fabs(metres);
  // Thresholds below 1 cm and 1 m so that a value rounding up shows in the next unit.
  if (a < 0.009995) return Printf("%.*f", 2, metres * 1e3) + " mm";
  if (a < 0.09995) return Printf("%.*f", 2, metres * 1e2) + " cm";
  if (a < 0.9995) return Printf("%.*f", 1, metres * 1e2) + " cm";
  return Printf("%.*f", 2, metres) + " m";
}

std::string FormatDegrees(double degrees) { return Significant(degrees, 3) + kDegreeSign; }

std::string FormatRecall(double percent) { return Printf("%.*f", 1, percent) + " %"; }

std::string FormatDuration(double seconds) {
  if (!std::isfinite(seconds)) return Significant(seconds, 3);
  if (std::abs(seconds) < 60) return Printf("%.*f s", 1, seconds);
  if (std::abs(seconds) < 3600) return Printf("%.*f min", 1, seconds / 60);
  return Printf("%.*f h", 1, seconds / 3600);
}

std::string FormatPercent(double percent) { return Significant(percent, 3) + " %"; }

std::string FormatPlain(const std::string& written, double value) {
  const bool integer = written.find_first_of(".eE") == std::string::npos;
  if (integer || (WrittenDigits(written) <= 5 && written.find_first_of("eE") == std::string::npos))
    return written;
  const double a = std::fabs(value);
  if (a != 0 && (a < 1e-4 || a >= 1e15)) return Printf("%.*g", 3, value);
  if (a >= 1e4) return Printf("%.*f", 0, value);
  return Significant(value, 4);
}

namespace {

std::string FormatNumber(const std::string& written, double v, Unit unit) {
  switch (unit) {
    case Unit::kMetres: return FormatLength(v);
    case Unit::kCentimetres: return FormatLength(v * 1e-2);
    case Unit::kMillimetres: return FormatLength(v * 1e-3);
    case Unit::kDegrees: return FormatDegrees(v);
    case Unit::kPercent: return FormatPercent(v);
    case Unit::kRecall: return FormatRecall(v);
    case Unit::kNone: break;
  }
  return FormatPlain(written, v);
}

std::vector<std::string> SplitList(const std::string& value) {
  std::vector<std::string> parts;
  size_t start = 0;
  for (size_t at; (at = value.find(" / ", start)) != std::string::npos; start = at + 3)
    parts.push_back(value.substr(start, at - start));
  parts.push_back(value.substr(start));
  return parts;
}

}  // namespace

std::string DisplayCell(const std::string& value, Unit unit) {
  double v;
  if (ParseNumber(value, &v)) return FormatNumber(value, v, unit);
  const std::vector<std::string> parts = SplitList(value);
  if (parts.size() < 2) return value;
  std::vector<std::string> shown;
  for (const std::string& p : parts) {
    if (!ParseNumber(p, &v)) return value;
    shown.push_back(FormatNumber(p, v, unit));
  }
  // "98.7 % / 100.0 %" -> "98.7 / 100.0 %" when every part has the same unit.
  const size_t space = shown[0].rfind(' ');
  const std::string suffix = space == std::string::npos ? "" : shown[0].substr(space);
  bool same = !suffix.empty();
  for (const std::string& s : shown) same = same && EndsWith(s, suffix);
  std::string out;
  for (const std::string& s : shown)
    out += (out.empty() ? "" : " / ") + (same ? s.substr(0, s.size() - suffix.size()) : s);
  return same ? out + suffix : out;
}

std::string ShortenNumbers(const std::string& text) {
  static const std::regex number(R"([-+]?\d+\.\d+(?:[eE][-+]?\d+)?)");
  std::string out;
  auto begin = std::sregex_iterator(text.begin(), text.end(), number);
  size_t last = 0;
  for (auto it = begin; it != std::sregex_iterator(); ++it) {
    const size_t at = static_cast<size_t>(it->position()), len = static_cast<size_t>(it->length());
    const auto word = [&](size_t i) {
      return i < text.size() && (std::isalnum(static_cast<unsigned char>(text[i])) || text[i] == '_' || text[i] == '.');
    };
    // Part of a name or version ("v1.2.3", "run-2.5x"): left alone.
    if ((at > 0 && word(at - 1)) || word(at + len)) continue;
    const std::string token = it->str();
    double v;
    if (WrittenDigits(token) <= 6 || !ParseNumber(token, &v)) continue;
    out += text.substr(last, at - last) + FormatPlain(token, v);
    last = at + len;
  }
  return out + text.substr(last);
}

std::string Table(const Csv& csv, const std::string& source, const std::string& caption,
                  const std::vector<std::string>& columns, Unit fallback) {
  std::vector<int> shown;
  if (columns.empty()) {
    for (size_t c = 0; c < csv.header.size(); ++c) shown.push_back(static_cast<int>(c));
  } else {
    for (const auto& name : columns)
      if (const int c = csv.Column(name); c >= 0) shown.push_back(c);
  }
  static const std::set<std::string> kStatistics = {"rmse", "mean", "median", "std", "min", "max"};
  std::string h = "<div class=\"table-wrap\"><table class=\"data\" data-source=\"" + Escape(source) + "\">";
  if (!caption.empty())
    h += "<caption>" + Escape(caption) + " <span class=\"source\">" + Escape(source) + "</span></caption>";
  h += "<thead><tr>";
  for (int c : shown) h += "<th data-column=\"" + std::to_string(c) + "\">" + Escape(csv.header[c]) + "</th>";
  h += "</tr></thead><tbody>";
  for (size_t r = 0; r < csv.rows.size(); ++r) {
    h += "<tr data-row=\"" + std::to_string(r) + "\">";
    const Unit row_unit = csv.rows[r].empty() ? Unit::kNone : UnitOf(csv.rows[r][0]);
    for (int c : shown) {
      const std::string& v = c < static_cast<int>(csv.rows[r].size()) ? csv.rows[r][c] : std::string();
      Unit unit = UnitOf(csv.header[c]);
      if (unit == Unit::kNone) unit = kStatistics.count(Lower(csv.header[c])) ? row_unit : fallback;
      double x;
      const bool number = ParseNumber(v, &x);
      h += std::string("<td") + (number ? " class=\"num\"" : "") + " data-value=\"" + Escape(v) + "\"" +
           (unit == Unit::kNone ? "" : std::string(" data-unit=\"") + Escape(UnitName(unit)) + "\"") + ">" +
           Escape(DisplayCell(v, unit)) + "</td>";
    }
    h += "</tr>";
  }
  h += "</tbody></table></div>\n";
  return h;
}

namespace {

std::string Fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f", v);
  return buf;
}

}  // namespace

std::string GraphSvg(const std::vector<RunRecord::Node>& nodes) {
  // Layers: a node sits one below the deepest node it reads.
  std::map<std::string, int> depth;
  std::map<std::string, const RunRecord::Node*> by_name;
  for (const auto& n : nodes) by_name[n.name] = &n;
  for (const auto& n : nodes) {  // the record is in topological order
    int d = 0;
    for (const auto& in : n.inputs)
      if (depth.count(in.node)) d = std::max(d, depth[in.node] + 1);
    depth[n.name] = d;
  }
  std::map<int, std::vector<const RunRecord::Node*>> layers;
  for (const auto& n : nodes) layers[depth[n.name]].push_back(&n);
  const double box_w = 168, box_h = 40, gap_x = 16, gap_y = 34, margin = 8;
  size_t widest = 1;
  for (const auto& [d, layer] : layers) widest = std::max(widest, layer.size());
  const double width = margin * 2 + widest * box_w + (widest - 1) * gap_x;
  const double height = margin * 2 + layers.size() * box_h + (layers.size() - 1) * gap_y;
  std::map<std::string, std::pair<double, double>> at;  // top-left of each box
  for (const auto& [d, layer] : layers) {
    const double row_w = layer.size() * box_w + (layer.size() - 1) * gap_x;
    double x = (width - row_w) / 2;
    for (const auto* n : layer) {
      at[n->name] = {x, margin + d * (box_h + gap_y)};
      x += box_w + gap_x;
    }
  }
  std::string s = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + Fmt(width) + "\" height=\"" +
                  Fmt(height) + "\" viewBox=\"0 0 " + Fmt(width) + " " + Fmt(height) +
                  "\" font-family=\"DejaVu Sans, Arial, sans-serif\">\n<title>graph</title>\n"
                  "<rect width=\"100%\" height=\"100%\" fill=\"#ffffff\"/>\n";
  for (const auto& n : nodes)
    for (const auto& in : n.inputs) {
      if (!at.count(in.node)) continue;
      const auto [x0, y0] = at[in.node];
      const auto [x1, y1] = at[n.name];
      const double ax = x0 + box_w / 2, ay = y0 + box_h, bx = x1 + box_w / 2, by = y1;
      const double my = (ay + by) / 2;
      s += "<path d=\"M" + Fmt(ax) + " " + Fmt(ay) + " C" + Fmt(ax) + " " + Fmt(my) + " " + Fmt(bx) + " " + Fmt(my) +
           " " + Fmt(bx) + " " + Fmt(by) + "\" fill=\"none\" stroke=\"#8a8a8a\" stroke-width=\"1\"/>\n";
    }
  for (const auto& n : nodes) {
    const auto [x, y] = at[n.name];
    const std::string fill = n.status == "ran" || n.status == "resumed" ? "#dbe9f6"
                             : n.status == "cached"                    ? "#eeeeee"
                             : n.status == "failed"                    ? "#f8d0c8"
                                                                       : "#fff8e0";
    const std::string stroke = n.status == "failed" ? "#d55e00" : "#5a5a5a";
    s += "<g><title>" + Escape(n.name + " (" + n.stage + ", " + n.status + ")") + "</title><rect x=\"" + Fmt(x) +
         "\" y=\"" + Fmt(y) + "\" width=\"" + Fmt(box_w) + "\" height=\"" + Fmt(box_h) +
         "\" rx=\"5\" fill=\"" + fill + "\" stroke=\"" + stroke + "\"/>";
    s += "<text x=\"" + Fmt(x + box_w / 2) + "\" y=\"" + Fmt(y + 17) +
         "\" text-anchor=\"middle\" font-size=\"12\" font-weight=\"bold\" fill=\"#1a1a1a\">" + Escape(n.name) +
         "</text>";
    s += "<text x=\"" + Fmt(x + box_w / 2) + "\" y=\"" + Fmt(y + 32) +
         "\" text-anchor=\"middle\" font-size=\"10\" fill=\"#444444\">" + Escape(n.stage) + "</text></g>\n";
  }
  s += "</svg>\n";
  return s;
}

}  // namespace locforge::host::report

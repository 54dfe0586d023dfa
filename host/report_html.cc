#include "report_html.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
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

std::string DisplayNumber(const std::string& value) {
  double v;
  if (!ParseNumber(value, &v)) return value;
  int digits = 0;
  bool leading = true;
  for (char c : value) {
    if (c == 'e' || c == 'E') break;
    if (!std::isdigit(static_cast<unsigned char>(c))) continue;
    if (leading && c == '0') continue;
    leading = false;
    ++digits;
  }
  const bool integer = value.find_first_of(".eE") == std::string::npos;
  if (integer || digits <= 5) return value;
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.4g", v);
  return buf;
}

std::string Table(const Csv& csv, const std::string& source, const std::string& caption,
                  const std::vector<std::string>& columns) {
  std::vector<int> shown;
  if (columns.empty()) {
    for (size_t c = 0; c < csv.header.size(); ++c) shown.push_back(static_cast<int>(c));
  } else {
    for (const auto& name : columns)
      if (const int c = csv.Column(name); c >= 0) shown.push_back(c);
  }
  std::string h = "<div class=\"table-wrap\"><table class=\"data\" data-source=\"" + Escape(source) + "\">";
  if (!caption.empty())
    h += "<caption>" + Escape(caption) + " <span class=\"source\">" + Escape(source) + "</span></caption>";
  h += "<thead><tr>";
  for (int c : shown) h += "<th data-column=\"" + std::to_string(c) + "\">" + Escape(csv.header[c]) + "</th>";
  h += "</tr></thead><tbody>";
  for (size_t r = 0; r < csv.rows.size(); ++r) {
    h += "<tr data-row=\"" + std::to_string(r) + "\">";
    for (int c : shown) {
      const std::string& v = c < static_cast<int>(csv.rows[r].size()) ? csv.rows[r][c] : std::string();
      double x;
      const bool number = ParseNumber(v, &x);
      h += std::string("<td") + (number ? " class=\"num\"" : "") + " data-value=\"" + Escape(v) + "\">" +
           Escape(DisplayNumber(v)) + "</td>";
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

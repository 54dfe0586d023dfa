#include "evaluation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "locforge/error.h"
#include "locforge/fs.h"

namespace locforge::evaluation {

QueryError ComputeError(const Pose& ground_truth, const std::optional<Pose>& estimate) {
  QueryError e;
  if (!estimate) return e;
  e.localized = true;
  e.position_m = (estimate->Center() - ground_truth.Center()).norm();
  e.rotation_deg = RotationAngleDeg(estimate->q, ground_truth.q);
  return e;
}

double Recall(const std::vector<QueryError>& errors, const Threshold& t) {
  if (errors.empty()) return 0;
  size_t good = 0;
  for (const auto& e : errors)
    good += e.localized && e.position_m <= t.position_m && e.rotation_deg <= t.rotation_deg;
  return static_cast<double>(good) / errors.size();
}

namespace {
double Median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string EscapeLatex(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '_': case '&': case '%': case '#': case '$': case '{': case '}':
        out += '\\';
        out += c;
        break;
      case '\\': out += "\\textbackslash{}"; break;
      case '^': out += "\\^{}"; break;
      case '~': out += "\\~{}"; break;
      default: out += c;
    }
  }
  return out;
}

std::string Num(double v, int digits = 2) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}
}  // namespace

double MedianPosition(const std::vector<QueryError>& errors) {
  std::vector<double> v;
  for (const auto& e : errors)
    if (e.localized) v.push_back(e.position_m);
  return Median(v);
}

double MedianRotation(const std::vector<QueryError>& errors) {
  std::vector<double> v;
  for (const auto& e : errors)
    if (e.localized) v.push_back(e.rotation_deg);
  return Median(v);
}

std::string Percent(double fraction) { return Num(100.0 * fraction, 1); }

std::string ToMarkdown(const Table& t) {
  std::ostringstream o;
  auto row = [&](const std::vector<std::string>& cells) {
    o << "|";
    for (const auto& c : cells) {
      std::string cell = c;
      for (size_t p = 0; (p = cell.find('|', p)) != std::string::npos; p += 2) cell.insert(p, "\\");
      o << " " << cell << " |";
    }
    o << "\n";
  };
  row(t.header);
  o << "|";
  for (size_t i = 0; i < t.header.size(); ++i) o << "---|";
  o << "\n";
  for (const auto& r : t.rows) row(r);
  return o.str();
}

std::string ToCsv(const Table& t) {
  std::ostringstream o;
  auto row = [&](const std::vector<std::string>& cells) {
    for (size_t i = 0; i < cells.size(); ++i) {
      const std::string& c = cells[i];
      if (i) o << ",";
      if (c.find_first_of(",\"\n\r") != std::string::npos) {
        o << '"';
        for (char ch : c) o << (ch == '"' ? "\"\"" : std::string(1, ch));
        o << '"';
      } else {
        o << c;
      }
    }
    o << "\n";
  };
  row(t.header);
  for (const auto& r : t.rows) row(r);
  return o.str();
}

std::string ReportMethod(const std::filesystem::path& report) {
  const std::filesystem::path file = report / "summary.csv";
  const Table summary = FromCsv(ReadFile(file), file.string());
  return summary.rows.empty() ? report.filename().string() : summary.rows[0][0];
}

Table FromCsv(const std::string& text, const std::string& file_name) {
  std::vector<std::vector<std::string>> lines;
  std::vector<std::string> cells;
  std::string cell;
  bool quoted = false, any = false;
  int line = 1;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        cell += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        if (c == '\n') ++line;
        cell += c;
      }
    } else if (c == '"') {
      quoted = true;
      any = true;
    } else if (c == ',') {
      cells.push_back(cell);
      cell.clear();
      any = true;
    } else if (c == '\n') {
      if (any || !cell.empty()) {
        cells.push_back(cell);
        lines.push_back(cells);
      }
      cells.clear();
      cell.clear();
      any = false;
      ++line;
    } else if (c != '\r') {
      cell += c;
    }
  }
  if (quoted) throw InputError(file_name, line, "", "unterminated quoted field");
  if (any || !cell.empty()) {
    cells.push_back(cell);
    lines.push_back(cells);
  }
  if (lines.empty()) throw InputError(file_name, 1, "", "empty CSV file");
  Table t;
  t.header = lines.front();
  for (size_t i = 1; i < lines.size(); ++i) {
    if (lines[i].size() != t.header.size())
      throw InputError(file_name, static_cast<int64_t>(i + 1), "",
                       "expected " + std::to_string(t.header.size()) + " fields, got " +
                           std::to_string(lines[i].size()));
    t.rows.push_back(lines[i]);
  }
  return t;
}

std::string ToLatex(const Table& t) {
  std::ostringstream o;
  o << "\\begin{tabular}{l";
  for (size_t i = 1; i < t.header.size(); ++i) o << "c";
  o << "}\n\\hline\n";
  auto row = [&](const std::vector<std::string>& cells) {
    for (size_t i = 0; i < cells.size(); ++i) o << (i ? " & " : "") << EscapeLatex(cells[i]);
    o << " \\\\\n";
  };
  row(t.header);
  o << "\\hline\n";
  for (const auto& r : t.rows) row(r);
  o << "\\hline\n\\end{tabular}\n";
  return o.str();
}

plot::Series RecallCurve(const std::vector<QueryError>& errors, const std::string& label,
                         double max_position_m, double angle_per_m, int steps, double log_decades) {
  plot::Series s;
  s.label = label;
  for (int i = 0; i <= steps; ++i) {
    const double p = log_decades > 0 ? max_position_m * std::pow(10.0, -log_decades * (steps - i) / steps)
                                     : max_position_m * i / steps;
    s.x.push_back(p);
    s.y.push_back(100 * Recall(errors, {p, angle_per_m * p}));
  }
  return s;
}

plot::Figure RecallFigure(std::vector<plot::Series> curves, const std::string& title,
                          double max_position_m, double angle_per_m) {
  plot::Figure f;
  f.title = title;
  f.x_label = "position threshold (m); rotation threshold " + Num(angle_per_m, 0) + "\xC2\xB0 per metre";
  f.y_label = "localized queries (%)";
  f.series = std::move(curves);
  f.x_log = true;
  f.x_min = max_position_m * std::pow(10.0, -kRecallDecades);
  f.x_max = max_position_m;
  f.y_min = 0;
  f.y_max = 100;
  return f;
}

}  // namespace locforge::evaluation

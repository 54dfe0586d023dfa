// locforge collect: one table of a node's result file over the variants of a
// matrix run (a sweep over seeds, an ablation), so nobody opens twenty
// folders: JSON files become one row per variant (nested keys joined with
// '.'), CSV files are concatenated with a variant column.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

#include "commands.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/kapture/csv.h"

namespace locforge::host {

namespace {

const char kCollectHelp[] = R"(Usage: locforge collect WORKSPACE NODE/FILE [--format csv|md] [--summary] [-o FILE]

One table of NODE's FILE over every variant of the workspace (a matrix run:
WORKSPACE/variants/<variant>/nodes/NODE/FILE; without a matrix, the one
WORKSPACE/nodes/NODE/FILE).
  .json  one row per variant: every scalar, nested keys joined with '.'
  .csv   the rows of every variant's file ('#' lines skipped), a variant column first
Variants are ordered by name, numbers compared as numbers (seed=2 before seed=10).

Options:
  --format csv|md   Output as CSV (default) or a Markdown table
  --summary         Add rows with the count, mean, min and max of numeric columns
  -o FILE           Write to FILE (atomically) instead of the standard output
)";

// "seed=10" after "seed=9": runs of digits compare as numbers.
bool NaturalLess(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (std::isdigit(static_cast<unsigned char>(a[i])) && std::isdigit(static_cast<unsigned char>(b[j]))) {
      size_t ie = i, je = j;
      while (ie < a.size() && std::isdigit(static_cast<unsigned char>(a[ie]))) ++ie;
      while (je < b.size() && std::isdigit(static_cast<unsigned char>(b[je]))) ++je;
      const std::string na = a.substr(i, ie - i), nb = b.substr(j, je - j);
      if (na.size() != nb.size()) return na.size() < nb.size();
      if (na != nb) return na < nb;
      i = ie, j = je;
      continue;
    }
    if (a[i] != b[j]) return a[i] < b[j];
    ++i, ++j;
  }
  return a.size() - i < b.size() - j;
}

struct Table {
  std::vector<std::string> columns;
  std::vector<std::vector<std::string>> rows;
  int Column(const std::string& name) {
    const auto it = std::find(columns.begin(), columns.end(), name);
    if (it != columns.end()) return static_cast<int>(it - columns.begin());
    columns.push_back(name);
    return static_cast<int>(columns.size()) - 1;
  }
};

void Flatten(const YAML::Node& node, const std::string& prefix, std::vector<std::pair<std::string, std::string>>* out) {
  if (node.IsScalar()) {
    out->emplace_back(prefix, node.Scalar());
  } else if (node.IsMap()) {
    for (const auto& kv : node)
      Flatten(kv.second, prefix.empty() ? kv.first.as<std::string>() : prefix + "." + kv.first.as<std::string>(), out);
  } else if (node.IsSequence() && node.size() <= 8) {
    // Short lists (e.g. [agreeing, conflicting, unseen]) as one column each.
    for (size_t i = 0; i < node.size(); ++i) Flatten(node[i], prefix + "." + std::to_string(i), out);
  }
}

void AddJson(const fs::path& file, const std::string& variant, Table* t) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw InputError(file.string(), e.mark.line + 1, "", std::string("not JSON: ") + e.msg);
  }
  std::vector<std::pair<std::string, std::string>> fields;
  Flatten(root, "", &fields);
  const int variant_column = t->Column("variant");  // may add the column: size the row after
  std::vector<std::string> row(t->columns.size());
  row[variant_column] = variant;
  for (const auto& [k, v] : fields) {
    const int c = t->Column(k);
    if (static_cast<int>(row.size()) <= c) row.resize(c + 1);
    row[c] = v;
  }
  t->rows.push_back(row);
}

void AddCsv(const fs::path& file, const std::string& variant, Table* t) {
  std::ifstream in(file);
  if (!in) throw InputError(file.string(), 0, "", "cannot read");
  std::string line;
  std::vector<std::string> header;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.empty() || line[0] == '#') continue;
    const std::vector<std::string> f = kapture::SplitCsvLine(line);
    if (header.empty()) {
      header = f;
      t->Column("variant");
      for (const auto& h : header) t->Column(h);
      continue;
    }
    if (f.size() != header.size())
      throw InputError(file.string(), n, "", "expected " + std::to_string(header.size()) + " fields, got " +
                                                 std::to_string(f.size()));
    std::vector<std::string> row(t->columns.size());
    row[t->Column("variant")] = variant;  // every column exists since the header
    for (size_t i = 0; i < f.size(); ++i) row[t->Column(header[i])] = f[i];
    t->rows.push_back(row);
  }
}

bool Number(const std::string& s, double* v) {
  if (s.empty()) return false;
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return end && *end == '\0';
}

void AddSummary(Table* t) {
  const size_t rows = t->rows.size();
  std::vector<std::vector<std::string>> extra(4, std::vector<std::string>(t->columns.size()));
  const char* names[] = {"(count)", "(mean)", "(min)", "(max)"};
  for (int k = 0; k < 4; ++k) extra[k][0] = names[k];
  for (size_t c = 1; c < t->columns.size(); ++c) {
    double sum = 0, lo = 1e300, hi = -1e300;
    size_t count = 0;
    bool all = true;
    for (size_t r = 0; r < rows; ++r) {
      const std::string& s = c < t->rows[r].size() ? t->rows[r][c] : std::string();
      double v;
      if (s == "true" || s == "false") {
        v = s == "true";
      } else if (!Number(s, &v)) {
        if (!s.empty()) all = false;
        continue;
      }
      sum += v, lo = std::min(lo, v), hi = std::max(hi, v), ++count;
    }
    if (!all || count == 0) continue;
    std::ostringstream a, m, l, h;
    a.precision(6), m.precision(6), l.precision(6), h.precision(6);
    a << count, m << sum / count, l << lo, h << hi;
    extra[0][c] = a.str(), extra[1][c] = m.str(), extra[2][c] = l.str(), extra[3][c] = h.str();
  }
  for (auto& e : extra) t->rows.push_back(e);
}

std::string Format(const Table& t, bool markdown) {
  std::ostringstream s;
  auto cell = [&](const std::vector<std::string>& row, size_t c) { return c < row.size() ? row[c] : std::string(); };
  if (markdown) {
    s << "|";
    for (const auto& c : t.columns) s << " " << c << " |";
    s << "\n|";
    for (size_t c = 0; c < t.columns.size(); ++c) s << "---|";
    s << "\n";
    for (const auto& row : t.rows) {
      s << "|";
      for (size_t c = 0; c < t.columns.size(); ++c) s << " " << cell(row, c) << " |";
      s << "\n";
    }
    return s.str();
  }
  auto quote = [](const std::string& v) {
    if (v.find_first_of(",\"\n") == std::string::npos) return v;
    std::string q = "\"";
    for (char ch : v) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
    return q + "\"";
  };
  for (size_t c = 0; c < t.columns.size(); ++c) s << (c ? "," : "") << quote(t.columns[c]);
  s << "\n";
  for (const auto& row : t.rows) {
    for (size_t c = 0; c < t.columns.size(); ++c) s << (c ? "," : "") << quote(cell(row, c));
    s << "\n";
  }
  return s.str();
}

}  // namespace

int CollectCommand(const Args& args) {
  std::vector<std::string> positional;
  std::string format = "csv", output;
  bool summary = false;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--help" || a == "-h") {
      std::cout << kCollectHelp;
      return 0;
    }
    if (a == "--summary") {
      summary = true;
    } else if ((a == "--format" || a == "-o") && i + 1 < args.size()) {
      (a == "--format" ? format : output) = args[++i];
    } else if (!a.empty() && a[0] == '-') {
      std::cerr << "locforge collect: unknown option '" << a << "'\nRun 'locforge collect --help' for usage.\n";
      return 2;
    } else {
      positional.push_back(a);
    }
  }
  if (positional.size() != 2 || (format != "csv" && format != "md")) {
    std::cerr << "locforge collect: expected WORKSPACE NODE/FILE (and --format csv|md)\n"
              << "Run 'locforge collect --help' for usage.\n";
    return 2;
  }
  const fs::path workspace = positional[0];
  const fs::path rel = positional[1];
  if (rel.is_absolute() || rel.lexically_normal().string().rfind("..", 0) == 0 || std::distance(rel.begin(), rel.end()) < 2) {
    std::cerr << "locforge collect: NODE/FILE must be a node name and a file inside it, e.g. joins/summary.json\n";
    return 2;
  }
  const std::string node = rel.begin()->string();
  const fs::path inside = rel.lexically_relative(node);
  std::vector<std::pair<std::string, fs::path>> files;  // variant -> file
  std::vector<std::string> missing;                     // variants without it (not run, or failed)
  std::error_code ec;
  if (fs::is_directory(workspace / "variants", ec)) {
    for (const auto& v : fs::directory_iterator(workspace / "variants", ec)) {
      const fs::path f = v.path() / "nodes" / node / inside;
      if (fs::exists(f, ec))
        files.emplace_back(v.path().filename().string(), f);
      else
        missing.push_back(v.path().filename().string());
    }
  } else if (fs::exists(workspace / "nodes" / node / inside, ec)) {
    files.emplace_back("-", workspace / "nodes" / node / inside);
  }
  if (files.empty()) {
    std::cerr << "locforge collect: no " << (fs::path(node) / inside).string() << " under " << workspace.string()
              << " (variants/*/nodes/ or nodes/): has the graph run?\n";
    return 1;
  }
  std::sort(files.begin(), files.end(), [](const auto& a, const auto& b) { return NaturalLess(a.first, b.first); });
  std::sort(missing.begin(), missing.end(), NaturalLess);
  for (const auto& v : missing)
    std::cerr << "locforge collect: " << v << ": no " << (fs::path(node) / inside).string()
              << " (not run yet, or failed): left out\n";
  try {
    Table t;
    const bool json = inside.extension() == ".json";
    for (const auto& [variant, f] : files) (json ? AddJson : AddCsv)(f, variant, &t);
    if (summary) AddSummary(&t);
    const std::string text = Format(t, format == "md");
    if (output.empty())
      std::cout << text;
    else
      WriteFileAtomic(output, text);
  } catch (const std::exception& e) {
    std::cerr << "locforge collect: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

}  // namespace locforge::host

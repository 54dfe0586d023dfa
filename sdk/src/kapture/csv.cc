#include "locforge/kapture/csv.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "locforge/error.h"

namespace locforge::kapture {

namespace {

bool IsBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f'; }

std::string Trim(const std::string& s) {
  size_t b = 0, e = s.size();
  while (b < e && IsBlank(s[b])) ++b;
  while (e > b && IsBlank(s[e - 1])) --e;
  return s.substr(b, e - b);
}

// Shows a bad value in a message without flooding it or printing raw bytes.
std::string Quote(const std::string& text) {
  std::string out;
  const size_t limit = 60;
  for (size_t i = 0; i < text.size() && i < limit; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\x%02x", c);
      out += buf;
    }
  }
  if (text.size() > limit) out += "...";
  return "'" + out + "'";
}

}  // namespace

std::vector<std::string> SplitCsvLine(const std::string& line) {
  std::vector<std::string> fields;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    if (comma == std::string::npos) {
      fields.push_back(Trim(line.substr(start)));
      break;
    }
    fields.push_back(Trim(line.substr(start, comma - start)));
    start = comma + 1;
  }
  return fields;
}

CsvReader::CsvReader(const fs::path& path, std::string display_name)
    : name_(display_name.empty() ? path.string() : std::move(display_name)) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw InputError(name_, 0, "", "is a folder, expected a file");
  owned_ = std::make_unique<std::ifstream>(path, std::ios::binary);
  if (!*owned_)
    throw InputError(name_, 0, "", std::string("cannot open file: ") + std::strerror(errno));
  in_ = owned_.get();
}

CsvReader::CsvReader(std::istream& in, std::string display_name)
    : in_(&in), name_(std::move(display_name)) {}

bool CsvReader::Next(CsvRow* row) {
  while (std::getline(*in_, buffer_)) {
    ++line_;
    if (buffer_.find('\0') != std::string::npos)
      throw InputError(name_, line_, "", "binary data (NUL byte) in a text file");
    size_t first = 0;
    while (first < buffer_.size() && IsBlank(buffer_[first])) ++first;
    if (first == buffer_.size()) continue;  // blank line
    if (buffer_[first] == '#') {
      std::string comment = Trim(buffer_.substr(first + 1));
      static const char kTag[] = "kapture format:";
      if (comment.compare(0, sizeof(kTag) - 1, kTag) == 0) {
        version_ = Trim(comment.substr(sizeof(kTag) - 1));
      }
      // Only the first few matter (version, column header); a file of
      // comments must not grow memory.
      if (comments_.size() < 16) comments_.push_back(std::move(comment));
      continue;
    }
    row->line = line_;
    row->fields = SplitCsvLine(buffer_);
    return true;
  }
  if (in_->bad()) throw InputError(name_, line_, "", "read error");
  return false;
}

double ParseDouble(const std::string& text, const std::string& file, int64_t line,
                   const std::string& field) {
  const std::string s = Trim(text);
  if (s.empty()) throw InputError(file, line, field, "expected a number, got an empty field");
  // Python's float() spellings of the special values (checked only when a
  // letter starts the number, to keep the common path cheap).
  const size_t lead = (s[0] == '+' || s[0] == '-') ? 1 : 0;
  if (lead < s.size() && std::isalpha(static_cast<unsigned char>(s[lead]))) {
    std::string body;
    for (size_t i = lead; i < s.size(); ++i)
      body += static_cast<char>(std::tolower(static_cast<unsigned char>(s[i])));
    if (body == "nan" || body == "inf" || body == "infinity") {
      const double v = body == "nan" ? std::nan("") : HUGE_VAL;
      return s[0] == '-' ? -v : v;
    }
  }
  const char* begin = s.data();
  const char* end = s.data() + s.size();
  if (*begin == '+') ++begin;  // from_chars refuses a leading '+', float() accepts it
  double value = 0;
  const auto result = std::from_chars(begin, end, value, std::chars_format::general);
  if (result.ec == std::errc::result_out_of_range) {
    // Python gives inf / 0.0 for these; strtod agrees.
    return std::strtod(s.c_str(), nullptr);
  }
  if (result.ec != std::errc() || result.ptr != end)
    throw InputError(file, line, field, "expected a number, got " + Quote(s));
  return value;
}

int64_t ParseInt64(const std::string& text, const std::string& file, int64_t line,
                   const std::string& field) {
  const std::string s = Trim(text);
  if (s.empty()) throw InputError(file, line, field, "expected an integer, got an empty field");
  const char* begin = s.data();
  const char* end = s.data() + s.size();
  if (*begin == '+') ++begin;
  int64_t value = 0;
  const auto result = std::from_chars(begin, end, value);
  if (result.ec == std::errc::result_out_of_range)
    throw InputError(file, line, field, "integer out of range: " + Quote(s));
  if (result.ec != std::errc() || result.ptr != end)
    throw InputError(file, line, field, "expected an integer, got " + Quote(s));
  return value;
}

void CheckFieldCount(const CsvRow& row, const std::string& file, size_t min_fields,
                     int64_t max_fields, const std::string& columns) {
  const size_t n = row.fields.size();
  if (n >= min_fields && (max_fields < 0 || static_cast<int64_t>(n) <= max_fields)) return;
  std::string expected;
  if (max_fields < 0) {
    expected = "at least " + std::to_string(min_fields);
  } else if (static_cast<int64_t>(min_fields) == max_fields) {
    expected = std::to_string(min_fields);
  } else {
    expected = std::to_string(min_fields) + " to " + std::to_string(max_fields);
  }
  throw InputError(file, row.line, "",
                   "expected " + expected + " fields (" + columns + "), got " + std::to_string(n));
}

std::string FormatDouble(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value < 0 ? "-inf" : "inf";
  if (value == 0) return std::signbit(value) ? "-0.0" : "0.0";
  // Shortest round-trip digits in scientific form: [-]d[.ddd]e[+-]XX.
  char buf[64];
  const auto result = std::to_chars(buf, buf + sizeof(buf), value, std::chars_format::scientific);
  std::string sci(buf, result.ptr);
  const bool negative = sci[0] == '-';
  if (negative) sci.erase(0, 1);
  const size_t e_pos = sci.find('e');
  std::string digits = sci.substr(0, e_pos);
  digits.erase(std::remove(digits.begin(), digits.end(), '.'), digits.end());
  const int exponent = std::atoi(sci.c_str() + e_pos + 1);
  std::string out;
  // repr() switches to exponent notation below 1e-4 and from 1e16 on.
  if (exponent < -4 || exponent >= 16) {
    out = digits.substr(0, 1);
    if (digits.size() > 1) out += "." + digits.substr(1);
    char exp_buf[16];
    std::snprintf(exp_buf, sizeof(exp_buf), "e%c%02d", exponent < 0 ? '-' : '+', std::abs(exponent));
    out += exp_buf;
  } else if (exponent < 0) {
    out = "0." + std::string(static_cast<size_t>(-exponent - 1), '0') + digits;
  } else {
    const size_t int_digits = static_cast<size_t>(exponent) + 1;
    if (digits.size() <= int_digits) {
      out = digits + std::string(int_digits - digits.size(), '0') + ".0";
    } else {
      out = digits.substr(0, int_digits) + "." + digits.substr(int_digits);
    }
  }
  return negative ? "-" + out : out;
}

std::string FormatDoubleSavetxt(double value) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.18e", value);
  return buf;
}

std::string JoinCsv(const std::vector<std::string>& fields) {
  std::string out;
  for (size_t i = 0; i < fields.size(); ++i) {
    if (i) out += ", ";
    out += fields[i];
  }
  return out;
}

}  // namespace locforge::kapture

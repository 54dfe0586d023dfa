#include "locforge/params.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>

namespace locforge {

const char* ParamTypeName(LfParamType type) {
  switch (type) {
    case LF_PARAM_BOOL: return "bool";
    case LF_PARAM_INT: return "int";
    case LF_PARAM_DOUBLE: return "double";
    case LF_PARAM_STRING: return "string";
    case LF_PARAM_PATH: return "path";
    case LF_PARAM_ENUM: return "enum";
    case LF_PARAM_INT_LIST: return "int list";
    case LF_PARAM_DOUBLE_LIST: return "double list";
    case LF_PARAM_STRING_LIST: return "string list";
    case LF_PARAM_COMPONENT: return "component";
  }
  return "unknown";
}

std::string FormatBool(bool v) { return v ? "true" : "false"; }
std::string FormatInt(int64_t v) { return std::to_string(v); }

std::string FormatDouble(double v) {
  // Shortest form that reads back to the same double, so "0.1" stays "0.1".
  char buf[64];
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  // %g writes round numbers such as 10 or 5000 as "1e+01", "5e+03": print
  // whole numbers below 1e16 in full instead (same value, same digits).
  if (const char* e = std::strchr(buf, 'e')) {
    const int exponent = std::atoi(e + 1);
    if (exponent > 0 && exponent < 16) std::snprintf(buf, sizeof(buf), "%.0f", v);
  }
  return buf;
}

std::string JoinList(const std::vector<std::string>& items) {
  std::string out;
  for (size_t i = 0; i < items.size(); ++i) {
    if (i) out += LF_LIST_SEPARATOR;
    out += items[i];
  }
  return out;
}

std::vector<std::string> SplitList(const std::string& canonical) {
  std::vector<std::string> out;
  if (canonical.empty()) return out;
  size_t start = 0;
  while (true) {
    const size_t pos = canonical.find(LF_LIST_SEPARATOR, start);
    out.push_back(canonical.substr(start, pos - start));
    if (pos == std::string::npos) break;
    start = pos + 1;
  }
  return out;
}

std::string FormatDegrees(double radians) {
  // Shortest decimal degrees that convert back to exactly `radians`, so a
  // default written DegreesToRadians(0.115) shows (and reads back) as 0.115.
  const double degrees = radians * 180.0 / M_PI;
  char buf[64];
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, degrees);
    if (DegreesToRadians(std::strtod(buf, nullptr)) == radians) return FormatDouble(std::strtod(buf, nullptr));
  }
  return FormatDouble(degrees);
}

const std::string* ComponentSpec::Find(const std::string& name) const {
  for (const auto& [k, v] : params)
    if (k == name) return &v;
  return nullptr;
}

ComponentSpec ComponentSpec::With(const std::string& name, const std::string& canonical) const {
  ComponentSpec out = *this;
  auto it = std::find_if(out.params.begin(), out.params.end(),
                         [&](const auto& kv) { return kv.first == name; });
  if (it != out.params.end()) {
    it->second = canonical;
  } else {
    out.params.emplace_back(name, canonical);
    std::sort(out.params.begin(), out.params.end());
  }
  return out;
}

std::string FormatComponent(const ComponentSpec& spec) {
  auto params = spec.params;
  std::sort(params.begin(), params.end());
  std::string out = spec.stage;
  for (const auto& [name, value] : params) out += LF_COMPONENT_SEPARATOR + name + "=" + value;
  return out;
}

bool ParseComponent(const std::string& canonical, ComponentSpec* out, std::string* why) {
  auto fail = [why](const std::string& reason) {
    if (why) *why = reason;
    return false;
  };
  ComponentSpec spec;
  size_t start = 0;
  bool first = true;
  while (true) {
    const size_t end = canonical.find(LF_COMPONENT_SEPARATOR, start);
    const std::string part = canonical.substr(start, end - start);
    if (first) {
      const size_t slash = part.find('/');
      if (slash == std::string::npos || slash == 0 || slash + 1 == part.size() ||
          part.find('/', slash + 1) != std::string::npos)
        return fail("expected a stage id KIND/NAME, got '" + part + "'");
      spec.stage = part;
      first = false;
    } else {
      const size_t eq = part.find('=');
      if (eq == std::string::npos || eq == 0)
        return fail("component parameter '" + part + "' is not name=value");
      const std::string name = part.substr(0, eq);
      if (spec.Find(name)) return fail("component parameter '" + name + "' given twice");
      spec.params.emplace_back(name, part.substr(eq + 1));
    }
    if (end == std::string::npos) break;
    start = end + 1;
  }
  std::sort(spec.params.begin(), spec.params.end());
  *out = std::move(spec);
  return true;
}

bool ParseBool(const std::string& s, bool* v) {
  static const std::set<std::string> kTrue = {"true", "True", "TRUE", "yes", "on", "1"};
  static const std::set<std::string> kFalse = {"false", "False", "FALSE", "no", "off", "0"};
  if (kTrue.count(s)) { *v = true; return true; }
  if (kFalse.count(s)) { *v = false; return true; }
  return false;
}

bool ParseInt(const std::string& s, int64_t* v) {
  // strtoll would skip leading blanks; the whole string must be the number.
  if (s.empty() || std::isspace(static_cast<unsigned char>(s[0]))) return false;
  errno = 0;
  char* end = nullptr;
  const long long x = std::strtoll(s.c_str(), &end, 10);
  if (errno != 0 || end != s.c_str() + s.size()) return false;
  *v = x;
  return true;
}

bool ParseDouble(const std::string& s, double* v) {
  if (s.empty() || std::isspace(static_cast<unsigned char>(s[0]))) return false;
  errno = 0;
  char* end = nullptr;
  const double x = std::strtod(s.c_str(), &end);
  // ERANGE also flags underflow to a subnormal, which FormatDouble can print:
  // only an overflow ("1e999") is refused.
  const bool overflow = errno == ERANGE && std::isinf(x);
  if (overflow || end != s.c_str() + s.size() || std::isnan(x)) return false;
  *v = x;
  return true;
}

namespace {

std::string RangeText(const ParamDecl& d) {
  std::string lo = d.has_min ? FormatDouble(d.min_value) : "-inf";
  std::string hi = d.has_max ? FormatDouble(d.max_value) : "+inf";
  return "[" + lo + ", " + hi + "]";
}

std::string CheckNumber(const ParamDecl& d, const std::string& s, bool integer) {
  double x = 0;
  if (integer) {
    int64_t i;
    if (!ParseInt(s, &i)) return "expected an integer, got '" + s + "'";
    x = static_cast<double>(i);
  } else if (!ParseDouble(s, &x)) {
    return "expected a number, got '" + s + "'";
  }
  if ((d.has_min && x < d.min_value) || (d.has_max && x > d.max_value))
    return "value " + s + " is out of range " + RangeText(d);
  return "";
}

}  // namespace

std::string ValidateParamValue(const ParamDecl& d, const std::string& value) {
  if (value.empty() && d.derived()) return "";  // not given: the stage derives it
  switch (d.type) {
    case LF_PARAM_BOOL: {
      bool b;
      return ParseBool(value, &b) ? "" : "expected true or false, got '" + value + "'";
    }
    case LF_PARAM_INT: return CheckNumber(d, value, true);
    case LF_PARAM_DOUBLE: return CheckNumber(d, value, false);
    case LF_PARAM_STRING: return "";
    // An optional path may be empty ("none given"); a required one may not.
    case LF_PARAM_PATH:
      return value.empty() && d.required() ? "expected a path, got an empty string" : "";
    case LF_PARAM_ENUM: {
      if (std::find(d.choices.begin(), d.choices.end(), value) != d.choices.end()) return "";
      std::string all;
      for (const auto& c : d.choices) all += (all.empty() ? "" : ", ") + c;
      std::string hint = DidYouMean(value, d.choices);
      return "'" + value + "' is not one of {" + all + "}" +
             (hint.empty() ? "" : " (did you mean '" + hint + "'?)");
    }
    case LF_PARAM_INT_LIST:
    case LF_PARAM_DOUBLE_LIST: {
      const auto items = SplitList(value);
      for (size_t i = 0; i < items.size(); ++i) {
        std::string why = CheckNumber(d, items[i], d.type == LF_PARAM_INT_LIST);
        if (!why.empty()) return "element " + std::to_string(i) + ": " + why;
      }
      return "";
    }
    case LF_PARAM_STRING_LIST: return "";
    // The component's own parameters are checked by the host against that
    // stage's declarations; here only the form.
    case LF_PARAM_COMPONENT: {
      ComponentSpec spec;
      std::string why;
      return ParseComponent(value, &spec, &why) ? "" : why;
    }
  }
  return "unknown parameter type";
}

std::map<std::string, std::string> ResolveParams(
    const std::vector<ParamDecl>& decls,
    const std::vector<std::pair<std::string, std::string>>& given) {
  std::map<std::string, std::string> out;
  std::vector<std::string> names;
  for (const auto& d : decls) names.push_back(d.name);
  for (const auto& [name, value] : given) {
    auto it = std::find_if(decls.begin(), decls.end(),
                           [&n = name](const ParamDecl& d) { return d.name == n; });
    if (it == decls.end()) {
      std::string hint = DidYouMean(name, names);
      throw ParamError("unknown parameter '" + name + "'" +
                       (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
    }
    if (out.count(name)) throw ParamError("parameter '" + name + "' given twice");
    const std::string why = ValidateParamValue(*it, value);
    if (!why.empty()) throw ParamError("parameter '" + name + "': " + why);
    out[name] = value;
  }
  for (const auto& d : decls) {
    if (out.count(d.name)) continue;
    if (d.required()) throw ParamError("parameter '" + d.name + "' is required (" + d.doc + ")");
    out[d.name] = d.default_value;
  }
  return out;
}

std::string DidYouMean(const std::string& word, const std::vector<std::string>& candidates) {
  // Edit distance where swapping two neighbouring letters ("ratoi") is one
  // edit, as are insertions, deletions and substitutions.
  auto distance = [](const std::string& a, const std::string& b) {
    std::vector<size_t> prev2(b.size() + 1), prev(b.size() + 1), cur(b.size() + 1);
    for (size_t j = 0; j <= b.size(); ++j) prev[j] = j;
    for (size_t i = 1; i <= a.size(); ++i) {
      cur[0] = i;
      for (size_t j = 1; j <= b.size(); ++j) {
        cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] != b[j - 1])});
        if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
          cur[j] = std::min(cur[j], prev2[j - 2] + 1);
      }
      std::swap(prev2, prev);
      std::swap(prev, cur);
    }
    return prev[b.size()];
  };
  std::string best;
  size_t best_d = std::max<size_t>(2, word.size() / 3) + 1;
  for (const auto& c : candidates) {
    const size_t d = distance(word, c);
    if (d < best_d) { best_d = d; best = c; }
  }
  return best;
}

}  // namespace locforge

// Command-line options of a tool (a bench, a recipe helper) declared through
// the same ParamSchema as a stage's: one declaration gives the flag, its
// default, its validation and its --help line.
//   --max-track 10  or  --max_track=10   (dashes and underscores are one)
#ifndef LOCFORGE_PARAM_CLI_H_
#define LOCFORGE_PARAM_CLI_H_

#include <algorithm>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "locforge/params.h"

namespace locforge {

// --help text: `head`, then one line per option with its type, default and doc.
template <typename Options>
std::string CommandLineHelp(const std::string& head) {
  std::string out = head;
  for (const ParamDecl& d : ParamSchema<Options>().Decls()) {
    std::string flag = d.name;
    std::replace(flag.begin(), flag.end(), '_', '-');
    out += "  --" + flag + " (" + ParamTypeName(d.type) + ", " +
           (d.required() ? std::string("required") : "default: " + d.default_value) + ")\n      " + d.doc + "\n";
  }
  return out;
}

// True when argv asks for --help / -h.
inline bool WantsHelp(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") return true;
  }
  return false;
}

// Parses `--key value` / `--key=value` into Options; throws ParamError naming
// the flag (unknown, malformed, out of range, missing).
template <typename Options>
Options ParseCommandLine(int argc, char** argv) {
  std::vector<std::pair<std::string, std::string>> given;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    if (a.rfind("--", 0) != 0) throw ParamError("expected --option, got '" + a + "'");
    a = a.substr(2);
    std::string value;
    if (const size_t eq = a.find('='); eq != std::string::npos) {
      value = a.substr(eq + 1);
      a = a.substr(0, eq);
    } else if (i + 1 < argc) {
      value = argv[++i];
    } else {
      throw ParamError("option --" + a + " has no value");
    }
    std::replace(a.begin(), a.end(), '-', '_');
    given.emplace_back(a, value);
  }
  return ParamSchema<Options>().Parse(given);
}

// A tool's main in one call: --help prints the help (exit code 0), a bad
// option prints the reason and the help on stderr (exit code 2); otherwise
// *options is filled and the result is -1 (go on).
//   Options o;
//   if (const int code = locforge::ParseToolOptions(argc, argv, kUsage, &o); code >= 0) return code;
template <typename Options>
int ParseToolOptions(int argc, char** argv, const std::string& head, Options* options) {
  if (WantsHelp(argc, argv)) {
    std::fputs(CommandLineHelp<Options>(head).c_str(), stdout);
    return 0;
  }
  try {
    *options = ParseCommandLine<Options>(argc, argv);
  } catch (const Error& e) {
    std::fprintf(stderr, "%s\n%s", e.what(), CommandLineHelp<Options>(head).c_str());
    return 2;
  }
  return -1;
}

}  // namespace locforge

#endif  // LOCFORGE_PARAM_CLI_H_

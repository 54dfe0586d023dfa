// Shared helpers of the plugins_abi tests.
#ifndef LOCFORGE_TESTS_PLUGINS_ABI_TEST_UTIL_H_
#define LOCFORGE_TESTS_PLUGINS_ABI_TEST_UTIL_H_

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "locforge/runtime/registry.h"
#include "testing.h"

namespace lftest {

namespace fs = std::filesystem;
using Params = std::vector<std::pair<std::string, std::string>>;

inline std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

// Runs a stage with a fresh instance; `logs` collects its log lines.
struct StageRun {
  const locforge::runtime::Registry* registry;
  std::string stage;
  Params params;
  locforge::runtime::RunOptions options;
  std::vector<std::string> logs;

  locforge::runtime::RunResult operator()() {
    const auto* entry = registry->Find(stage);
    if (entry == nullptr) throw std::runtime_error("stage " + stage + " not loaded");
    locforge::runtime::StageInstance instance(
        *entry, locforge::runtime::CheckStageParams(*entry, params));
    options.log = [this](int, const std::string& m) { logs.push_back(m); };
    return instance.Run(options);
  }
  std::vector<std::string> LogsStartingWith(const std::string& prefix) const {
    std::vector<std::string> out;
    for (const auto& l : logs)
      if (l.rfind(prefix, 0) == 0) out.push_back(l);
    return out;
  }
};

// Makes a synthetic kapture dataset with the examples plugin; returns its folder.
inline fs::path MakeSyntheticDataset(const locforge::runtime::Registry& registry,
                                     const fs::path& dir, int count, bool color = false) {
  StageRun run{&registry, "source/synthetic_images",
          {{"count", std::to_string(count)}, {"width", "40"}, {"height", "30"},
           {"seed", "7"}, {"color", color ? "true" : "false"}}, {}, {}};
  run.options.workspace = dir;
  run.options.output_dir = dir / "dataset";
  run();
  return dir / "dataset";
}

}  // namespace lftest

#endif  // LOCFORGE_TESTS_PLUGINS_ABI_TEST_UTIL_H_

#include "testing.h"

#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <sys/wait.h>

namespace locforge::testing {

std::filesystem::path SharedDir() {
  if (const char* env = std::getenv("LOCFORGE_SHARED_DIR"); env && *env) return env;
  return LOCFORGE_DEFAULT_SHARED_DIR;
}

bool SharedRequired() {
  const char* env = std::getenv("LOCFORGE_REQUIRE_SHARED");
  return env && std::string(env) == "1";
}

std::filesystem::path MakeTempDir(const std::string& prefix) {
  std::random_device rd;
  const auto dir = std::filesystem::temp_directory_path() /
                   (prefix + "-" + std::to_string(::getpid()) + "-" + std::to_string(rd()));
  std::filesystem::create_directories(dir);
  return dir;
}

std::string ShellQuote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

int RunHost(const std::filesystem::path& binary_dir, const std::vector<std::string>& args,
            const std::filesystem::path& log) {
  std::string cmd = "LOCFORGE_PLUGIN_PATH=" + ShellQuote((binary_dir / "lib/locforge/plugins").string()) +
                    " " + ShellQuote((binary_dir / "bin/locforge").string());
  for (const std::string& a : args) cmd += " " + ShellQuote(a);
  cmd += " > " + ShellQuote(log.string()) + " 2>&1";
  const int status = std::system(cmd.c_str());
  return status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::filesystem::path SimulateRecording(const std::filesystem::path& binary_dir,
                                        const std::filesystem::path& dir, const std::string& params) {
  std::ofstream(dir / "sim.yaml") << "locforge: 1\nnodes:\n  recording:\n    stage: source/simulator\n"
                                  << "    params: " << params << "\n";
  if (RunHost(binary_dir, {"run", (dir / "sim.yaml").string(), "--workspace", (dir / "sim").string()},
              dir / "sim.log") != 0)
    return {};
  return std::filesystem::canonical(dir / "sim/nodes/recording");
}

std::string ReadText(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

std::vector<std::vector<std::string>> ReadCsv(const std::filesystem::path& file) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(ReadText(file));
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::vector<std::string> cells(1);
    bool quoted = false;
    for (size_t i = 0; i < line.size(); ++i) {
      const char c = line[i];
      if (quoted && c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        cells.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = !quoted;
      } else if (c == ',' && !quoted) {
        cells.emplace_back();
      } else {
        cells.back() += c;
      }
    }
    rows.push_back(cells);
  }
  return rows;
}

}  // namespace locforge::testing

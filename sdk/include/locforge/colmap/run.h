// Running the `colmap` executable from a plugin or the host: no shell, the
// arguments as a vector, stdout and stderr captured in a log file.
#ifndef LOCFORGE_COLMAP_RUN_H_
#define LOCFORGE_COLMAP_RUN_H_

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace locforge::colmap {

struct RunOptions {
  // Where colmap's stdout and stderr go (created or truncated). Required:
  // COLMAP is verbose and its log is the only record of what it did.
  std::filesystem::path log_file;
  // Working directory of the child; empty = the caller's.
  std::filesystem::path working_dir;
  // Seconds before the child is killed (SIGTERM, then SIGKILL after 5 s);
  // 0 = no limit.
  double timeout_s = 0;
  // The executable; empty = $LOCFORGE_COLMAP, else `colmap` searched in PATH.
  std::string executable;
  // Polled every 20 ms while colmap runs; when it returns true the child's
  // process group is stopped like on a timeout and RunColmap throws
  // Cancelled. A stage passes its RunContext::cancelled() here so that
  // Ctrl-C on the host stops a long colmap run (the child has its own
  // process group and does not see the terminal's SIGINT). Empty = never.
  std::function<bool()> cancelled;

  bool Check(std::string* why) const;
};

struct RunResult {
  std::string executable;  // the resolved path that ran
  double seconds = 0;      // wall time
};

// The colmap executable that RunColmap would use (the option, else
// $LOCFORGE_COLMAP, else `colmap` in PATH), or "" when none is found.
std::string FindColmapExecutable(const std::string& preferred = "");

// Runs `colmap args...` and waits. Throws Error when colmap cannot be found
// ("colmap executable not found: set LOCFORGE_COLMAP or add it to PATH"),
// cannot start, exits non-zero, dies on a signal or times out, and
// Cancelled when options.cancelled() turns true; the message
// holds the command, the exit status, COLMAP's own last error lines
// ("Check failed", "ERROR", glog E/F lines) and the log file path.
RunResult RunColmap(const std::vector<std::string>& args, const RunOptions& options);

// COLMAP's error lines from a log text (at most `max_lines`, the last ones),
// or its last non-empty lines when it printed no recognised error.
std::vector<std::string> ColmapErrorLines(const std::string& log, size_t max_lines = 6);

}  // namespace locforge::colmap

#endif  // LOCFORGE_COLMAP_RUN_H_

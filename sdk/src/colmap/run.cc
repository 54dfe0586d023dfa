#include "locforge/colmap/run.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <fstream>
#include <sstream>
#include <thread>

#include "locforge/error.h"

extern char** environ;

namespace locforge::colmap {

namespace fs = std::filesystem;

bool RunOptions::Check(std::string* why) const {
  if (log_file.empty()) {
    if (why) *why = "log_file must be set";
    return false;
  }
  if (timeout_s < 0) {
    if (why) *why = "timeout_s must be >= 0";
    return false;
  }
  return true;
}

namespace {

bool IsExecutableFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec) && ::access(p.c_str(), X_OK) == 0;
}

std::string Quote(const std::vector<std::string>& argv) {
  std::string s;
  for (const std::string& a : argv) {
    if (!s.empty()) s += ' ';
    s += a.find_first_of(" \t\"'") == std::string::npos ? a : "'" + a + "'";
  }
  return s;
}

std::string ReadTail(const fs::path& path, size_t max_bytes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "";
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  const std::streamoff start = size > static_cast<std::streamoff>(max_bytes)
                                   ? size - static_cast<std::streamoff>(max_bytes)
                                   : 0;
  in.seekg(start);
  std::string s(static_cast<size_t>(size - start), '\0');
  in.read(s.data(), static_cast<std::streamsize>(s.size()));
  return s;
}

// glog prefixes: "E1122 04:00:00.123456 1234 file.cc:12] ..." (E = error, F = fatal).
bool IsGlogError(const std::string& line) {
  return line.size() > 5 && (line[0] == 'E' || line[0] == 'F') &&
         std::isdigit(static_cast<unsigned char>(line[1])) &&
         std::isdigit(static_cast<unsigned char>(line[4]));
}

// SIGTERM to the child's process group, 5 s to exit, then SIGKILL; reaps the child.
void StopProcessGroup(pid_t pid, int* status) {
  ::kill(-pid, SIGTERM);
  for (int i = 0; i < 50 && ::waitpid(pid, status, WNOHANG) == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ::kill(-pid, SIGKILL);
  ::waitpid(pid, status, 0);
}

}  // namespace

std::vector<std::string> ColmapErrorLines(const std::string& log, size_t max_lines) {
  std::deque<std::string> errors, last;
  std::istringstream in(log);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    if (line.find("Check failed") != std::string::npos || line.find("ERROR") != std::string::npos ||
        line.find("error:") != std::string::npos || IsGlogError(line) ||
        line.find("terminate called") != std::string::npos) {
      errors.push_back(line);
      if (errors.size() > max_lines) errors.pop_front();
    }
    last.push_back(line);
    if (last.size() > max_lines) last.pop_front();
  }
  const std::deque<std::string>& pick = errors.empty() ? last : errors;
  return {pick.begin(), pick.end()};
}

std::string FindColmapExecutable(const std::string& preferred) {
  std::string name = preferred;
  if (name.empty()) {
    const char* env = std::getenv("LOCFORGE_COLMAP");
    name = env && *env ? env : "colmap";
  }
  if (name.find('/') != std::string::npos) return IsExecutableFile(name) ? name : "";
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path ? path : "/usr/local/bin:/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const fs::path candidate = fs::path(dir.empty() ? "." : dir) / name;
    if (IsExecutableFile(candidate)) return candidate.string();
  }
  return "";
}

namespace {

[[noreturn]] void ThrowNotFound(const RunOptions& options) {
  const char* env = std::getenv("LOCFORGE_COLMAP");
  throw Error(std::string("colmap executable not found") +
              (options.executable.empty() && env && *env
                   ? " at LOCFORGE_COLMAP=" + std::string(env)
                   : options.executable.empty() ? " in PATH" : ": " + options.executable) +
              "; install COLMAP 3.8, or set LOCFORGE_COLMAP to its path");
}

// The log file, created with the command as its first line: its descriptor.
int OpenLog(const fs::path& log_file, const std::string& command) {
  if (log_file.has_parent_path()) fs::create_directories(log_file.parent_path());
  const int log_fd = ::open(log_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (log_fd < 0) {
    throw Error("cannot create colmap log " + log_file.string() + ": " + std::strerror(errno));
  }
  const std::string header = "$ " + command + "\n";
  [[maybe_unused]] const ssize_t w = ::write(log_fd, header.data(), header.size());
  return log_fd;
}

// Starts argv[0] with stdin from /dev/null and stdout and stderr into log_fd
// (closed here), in working_dir when given. The child gets its own process
// group so a timeout can stop colmap's children too.
pid_t Spawn(const std::string& executable, std::vector<char*>& argv, int log_fd, const fs::path& working_dir,
            const std::string& command) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, log_fd, STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, log_fd, STDERR_FILENO);
  if (!working_dir.empty()) {
#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 29))
    posix_spawn_file_actions_addchdir_np(&actions, working_dir.c_str());
#else
#error "posix_spawn_file_actions_addchdir_np is needed (glibc >= 2.29)"
#endif
  }
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attr, 0);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, executable.c_str(), &actions, &attr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  ::close(log_fd);
  if (rc != 0) {
    throw Error("cannot start " + command + ": " + std::strerror(rc));
  }
  return pid;
}

// Waits for pid: polls (20 ms) when a timeout or a cancel callback can end
// the wait early, then stops its process group. The wait status.
int Wait(pid_t pid, const RunOptions& options, std::chrono::steady_clock::time_point start,
         const std::string& command, bool* timed_out, bool* cancelled) {
  const bool poll = options.timeout_s > 0 || static_cast<bool>(options.cancelled);
  int status = 0;
  for (;;) {
    const pid_t w = ::waitpid(pid, &status, poll ? WNOHANG : 0);
    if (w == pid) break;
    if (w < 0 && errno != EINTR) throw Error("waitpid failed for " + command + ": " + std::strerror(errno));
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    *timed_out = options.timeout_s > 0 && elapsed > options.timeout_s;
    *cancelled = !*timed_out && options.cancelled && options.cancelled();
    if (*timed_out || *cancelled) {
      StopProcessGroup(pid, &status);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return status;
}

// Why the run failed ("" when it did not).
std::string FailureOf(int status, bool timed_out, double timeout_s) {
  if (timed_out) return "timed out after " + std::to_string(timeout_s) + " s";
  if (WIFSIGNALED(status))
    return "killed by signal " + std::to_string(WTERMSIG(status)) + " (" + strsignal(WTERMSIG(status)) + ")";
  if (WIFEXITED(status) && WEXITSTATUS(status) != 0) return "exit status " + std::to_string(WEXITSTATUS(status));
  return "";
}

// The failure with what colmap said (the log's error lines, else its last lines).
[[noreturn]] void ThrowFailed(const std::string& failure, const std::string& command, const fs::path& log_file) {
  std::string message = "colmap failed (" + failure + "): " + command;
  const std::vector<std::string> lines = ColmapErrorLines(ReadTail(log_file, 64 * 1024));
  if (!lines.empty()) {
    message += "\ncolmap said:";
    for (const std::string& l : lines) message += "\n  " + l;
  }
  message += "\nfull log: " + log_file.string();
  throw Error(message);
}

}  // namespace

RunResult RunColmap(const std::vector<std::string>& args, const RunOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw ParamError("RunColmap: " + why);
  RunResult result;
  result.executable = FindColmapExecutable(options.executable);
  if (result.executable.empty()) ThrowNotFound(options);
  std::vector<std::string> argv_s{result.executable};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  const std::string command = Quote(argv_s);
  const int log_fd = OpenLog(options.log_file, command);
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = Spawn(result.executable, argv, log_fd, options.working_dir, command);
  bool timed_out = false, cancelled = false;
  const int status = Wait(pid, options, start, command, &timed_out, &cancelled);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (cancelled) throw Cancelled();
  const std::string failure = FailureOf(status, timed_out, options.timeout_s);
  if (failure.empty()) return result;
  ThrowFailed(failure, command, options.log_file);
}

}  // namespace locforge::colmap

#include "process.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>

extern char** environ;

namespace locforge::host {

namespace {

struct Pipe {
  int fd[2] = {-1, -1};
  ~Pipe() {
    for (int f : fd)
      if (f >= 0) ::close(f);
  }
  void CloseRead() { Close(0); }
  void CloseWrite() { Close(1); }
  void Close(int i) {
    if (fd[i] >= 0) ::close(fd[i]);
    fd[i] = -1;
  }
};

// Starts argv with stdin from /dev/null and stdout, stderr into the pipes'
// write ends; the child starts with default signal handling and nothing
// blocked. 0 or the error number.
int Spawn(const std::vector<std::string>& argv, const Pipe& out, const Pipe& err, pid_t* pid) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, out.fd[1], 1);
  posix_spawn_file_actions_adddup2(&actions, err.fd[1], 2);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attr, &none);
  sigset_t defaults;
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGINT);
  sigaddset(&defaults, SIGTERM);
  sigaddset(&defaults, SIGPIPE);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const int rc = ::posix_spawnp(pid, argv[0].c_str(), &actions, &attr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  return rc;
}

// One poll (200 ms) of the open read ends: what is ready appended to r.out
// and r.err, a pipe that ended closed. False when poll failed.
bool ReadOnce(Pipe& out, Pipe& err, ProcessResult* r) {
  pollfd fds[2];
  nfds_t n = 0;
  for (Pipe* p : {&out, &err})
    if (p->fd[0] >= 0) fds[n++] = {p->fd[0], POLLIN, 0};
  const int ready = ::poll(fds, n, 200);
  if (ready < 0 && errno != EINTR) return false;
  for (nfds_t i = 0; i < n && ready > 0; ++i) {
    if (!(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
    Pipe* p = fds[i].fd == out.fd[0] ? &out : &err;
    char buf[65536];
    const ssize_t got = ::read(fds[i].fd, buf, sizeof(buf));
    if (got > 0)
      (p == &out ? r->out : r->err).append(buf, static_cast<size_t>(got));
    else if (got == 0 || (errno != EINTR && errno != EAGAIN))
      p->CloseRead();
  }
  return true;
}

// Reads both pipes to their end; past the timeout, SIGTERM, then SIGKILL 2 s later.
void Collect(pid_t pid, double timeout_seconds, Pipe& out, Pipe& err, ProcessResult* r) {
  const auto start = std::chrono::steady_clock::now();
  bool term_sent = false;
  std::chrono::steady_clock::time_point term_time;
  while (out.fd[0] >= 0 || err.fd[0] >= 0) {
    if (!ReadOnce(out, err, r)) break;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (timeout_seconds > 0 && elapsed > timeout_seconds) {
      if (!term_sent) {
        ::kill(pid, SIGTERM);
        term_sent = true;
        term_time = std::chrono::steady_clock::now();
        r->timed_out = true;
      } else if (std::chrono::steady_clock::now() - term_time > std::chrono::seconds(2)) {
        ::kill(pid, SIGKILL);
        break;
      }
    }
  }
}

}  // namespace

std::string DisplayCommand(const std::vector<std::string>& argv) {
  std::string s;
  for (const auto& a : argv) {
    if (!s.empty()) s += ' ';
    if (!a.empty() && a.find_first_of(" \t\n\"'\\$`;&|<>()*?[]{}~#") == std::string::npos) {
      s += a;
    } else {
      s += '\'';
      for (char c : a) s += c == '\'' ? std::string("'\\''") : std::string(1, c);
      s += '\'';
    }
  }
  return s;
}

ProcessResult RunProcess(const std::vector<std::string>& argv, double timeout_seconds) {
  ProcessResult r;
  if (argv.empty()) {
    r.error = "no program given";
    return r;
  }
  Pipe out, err;
  if (::pipe2(out.fd, O_CLOEXEC) != 0 || ::pipe2(err.fd, O_CLOEXEC) != 0) {
    r.error = std::string("pipe: ") + std::strerror(errno);
    return r;
  }
  pid_t pid = -1;
  if (const int rc = Spawn(argv, out, err, &pid); rc != 0) {
    r.error = "cannot run '" + argv[0] + "': " + std::strerror(rc);
    return r;
  }
  r.started = true;
  out.CloseWrite();
  err.CloseWrite();
  Collect(pid, timeout_seconds, out, err, &r);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (r.timed_out) r.error = "'" + argv[0] + "' timed out after " +
                             std::to_string(static_cast<int>(timeout_seconds)) + " s";
  else if (WIFSIGNALED(status))
    r.error = "'" + argv[0] + "' was killed by signal " + std::to_string(WTERMSIG(status));
  return r;
}

}  // namespace locforge::host

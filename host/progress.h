// What a run shows: a progress bar per node on a terminal, plain lines
// otherwise (no carriage returns, for logs and CI), plugin log lines, and a
// copy of everything in the run's log file. Thread-safe: per-item stages
// report from their worker threads.
#ifndef LOCFORGE_HOST_PROGRESS_H_
#define LOCFORGE_HOST_PROGRESS_H_

#include <chrono>
#include <cstdint>
#include <fstream>
#include <mutex>
#include <ostream>
#include <string>

namespace locforge::host {

class Reporter {
 public:
  // `out` is the console stream (stderr); `tty` draws bars with '\r'.
  Reporter(std::ostream& out, bool tty);

  // Copies every later line into `file` as well.
  void OpenLogFile(const std::string& file);

  void NodeStarted(const std::string& label, const std::string& stage);
  void Progress(const std::string& label, uint64_t done, uint64_t total, const std::string& what);
  void NodeFinished(const std::string& label, const std::string& status, uint64_t items,
                    double seconds);
  // A plugin log line (level: LF_LOG_*) or a host message.
  void Log(const std::string& label, int level, const std::string& message);
  void Line(const std::string& text);
  // Into the log file only.
  void FileOnly(const std::string& text);

 private:
  void ClearBar();                      // call with mutex_ held
  void Write(const std::string& text);  // a whole line, console + log

  std::ostream& out_;
  bool tty_;
  std::ofstream log_;
  std::mutex mutex_;
  bool bar_shown_ = false;
  uint64_t last_reported_ = 0;
  std::chrono::steady_clock::time_point last_time_;
};

}  // namespace locforge::host

#endif  // LOCFORGE_HOST_PROGRESS_H_

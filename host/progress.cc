#include "progress.h"

#include "locforge/abi.h"
#include "workspace.h"

namespace locforge::host {

Reporter::Reporter(std::ostream& out, bool tty) : out_(out), tty_(tty) {}

void Reporter::OpenLogFile(const std::string& file) {
  std::lock_guard<std::mutex> lock(mutex_);
  log_.open(file, std::ios::app);
}

void Reporter::ClearBar() {
  if (tty_ && bar_shown_) {
    out_ << "\r\033[K";
    bar_shown_ = false;
  }
}

void Reporter::Write(const std::string& text) {
  ClearBar();
  out_ << text << "\n";
  out_.flush();
  if (log_.is_open()) log_ << UtcNow() << " " << text << "\n" << std::flush;
}

void Reporter::Line(const std::string& text) {
  std::lock_guard<std::mutex> lock(mutex_);
  Write(text);
}

void Reporter::FileOnly(const std::string& text) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (log_.is_open()) log_ << UtcNow() << " " << text << "\n" << std::flush;
}

void Reporter::NodeStarted(const std::string& label, const std::string& stage) {
  std::lock_guard<std::mutex> lock(mutex_);
  last_reported_ = 0;
  last_time_ = std::chrono::steady_clock::now();
  Write(label + ": running " + stage);
}

void Reporter::Progress(const std::string& label, uint64_t done, uint64_t total,
                        const std::string& what) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto now = std::chrono::steady_clock::now();
  if (tty_) {
    // Redraw at most 10 times a second, and always the last one.
    if (done != total && now - last_time_ < std::chrono::milliseconds(100)) return;
    last_time_ = now;
    constexpr int kWidth = 30;
    const int filled = total ? static_cast<int>(kWidth * done / total) : 0;
    out_ << "\r\033[K" << label << " [" << std::string(filled, '#')
         << std::string(kWidth - filled, '.') << "] " << done << "/" << total
         << (what.empty() ? "" : " " + what) << std::flush;
    bar_shown_ = true;
    return;
  }
  // Plain output: every 10% or every 5 seconds.
  const uint64_t step = total >= 10 ? total / 10 : 1;
  if (done != total && done < last_reported_ + step && now - last_time_ < std::chrono::seconds(5))
    return;
  last_reported_ = done;
  last_time_ = now;
  Write(label + ": " + std::to_string(done) + "/" + std::to_string(total) +
        (what.empty() ? "" : " " + what));
}

void Reporter::NodeFinished(const std::string& label, const std::string& status, uint64_t items,
                            double seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2f", seconds);
  Write(label + ": " + status + (items ? ", " + std::to_string(items) + " items" : "") + " in " +
        buf + " s");
}

void Reporter::Log(const std::string& label, int level, const std::string& message) {
  const char* tag = level >= LF_LOG_WARNING ? "warning: " : level <= LF_LOG_DEBUG ? "debug: " : "";
  std::lock_guard<std::mutex> lock(mutex_);
  if (level <= LF_LOG_DEBUG) {  // debug lines go to the log file only
    if (log_.is_open()) log_ << UtcNow() << " " << label << ": " << tag << message << "\n";
    return;
  }
  Write(label + ": " + tag + message);
}

}  // namespace locforge::host

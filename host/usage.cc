#include "usage.h"

#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <fstream>
#include <string>

namespace locforge::host {

namespace {

double CpuSeconds(const rusage& u) {
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

rusage Get(int who) {
  rusage u{};
  ::getrusage(who, &u);
  return u;
}

}  // namespace

uint64_t ProcessPeakRss() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmHWM:", 0) == 0) return 1024ull * std::stoull(line.substr(6));  // kB
  return 0;
}

UsageMeter::UsageMeter() {
  const int fd = ::open("/proc/self/clear_refs", O_WRONLY | O_CLOEXEC);
  if (fd >= 0) {
    reset_ = ::write(fd, "5", 1) == 1;
    ::close(fd);
  }
  const rusage self = Get(RUSAGE_SELF), children = Get(RUSAGE_CHILDREN);
  self_cpu_ = CpuSeconds(self);
  children_cpu_ = CpuSeconds(children);
  children_peak_ = 1024ull * static_cast<uint64_t>(children.ru_maxrss);
}

Usage UsageMeter::Stop() const {
  const rusage self = Get(RUSAGE_SELF), children = Get(RUSAGE_CHILDREN);
  Usage u;
  u.cpu_seconds = CpuSeconds(self) - self_cpu_ + CpuSeconds(children) - children_cpu_;
  u.peak_rss_bytes = ProcessPeakRss();
  // ru_maxrss of the children is their largest peak so far: when it grew, a
  // child of this node set it.
  const uint64_t children_peak = 1024ull * static_cast<uint64_t>(children.ru_maxrss);
  if (children_peak > children_peak_ && children_peak > u.peak_rss_bytes)
    u.peak_rss_bytes = children_peak;
  u.peak_exact = reset_;
  return u;
}

}  // namespace locforge::host

// What computing one node cost the process that ran it: CPU time (its
// threads and the child processes it waited for, e.g. `colmap`) and peak
// resident memory, measured around the node (getrusage, /proc/self/status).
#ifndef LOCFORGE_HOST_USAGE_H_
#define LOCFORGE_HOST_USAGE_H_

#include <cstdint>

namespace locforge::host {

struct Usage {
  double cpu_seconds = 0;       // user + system, this process and its reaped children
  uint64_t peak_rss_bytes = 0;  // the larger of this process's peak and its largest child's
  bool peak_exact = true;       // false: the peak could not be reset, it is the process's so far
};

// Starts measuring: resets the process's peak resident size to its current
// one (writes 5 to /proc/self/clear_refs, Linux >= 4.0) and notes the CPU
// times. Stop() returns what was used since.
class UsageMeter {
 public:
  UsageMeter();
  Usage Stop() const;

 private:
  double self_cpu_ = 0, children_cpu_ = 0;
  uint64_t children_peak_ = 0;
  bool reset_ = false;
};

// Peak resident size of this process (VmHWM), 0 when unknown.
uint64_t ProcessPeakRss();

}  // namespace locforge::host

#endif  // LOCFORGE_HOST_USAGE_H_

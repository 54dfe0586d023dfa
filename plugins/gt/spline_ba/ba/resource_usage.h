// Process resource usage for the BA benchmarks (getrusage, Linux units).
#ifndef LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_RESOURCE_USAGE_H_
#define LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_RESOURCE_USAGE_H_

#include <sys/resource.h>

namespace locforge::sfm {

// Peak resident set size of this process so far, MB.
inline double PeakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // Linux: kilobytes
}

// User + system CPU time of this process so far, seconds.
inline double CpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_utime.tv_sec + usage.ru_stime.tv_sec +
         1e-6 * (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

}  // namespace locforge::sfm

#endif  // LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_RESOURCE_USAGE_H_

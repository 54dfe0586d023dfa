// f(i) for every i in [0, n) on a few threads: the one loop the bundle
// adjuster's solvers parallelise with.
#ifndef LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_PARALLEL_FOR_H_
#define LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_PARALLEL_FOR_H_

#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

namespace locforge::sfm {

// f(i) for every i in [0, n), `grain` consecutive indices at a time, on
// `threads` threads (the caller's among them). f must not throw. Which thread
// runs which i varies; callers keep every sum's order independent of it.
template <typename F>
void ParallelFor(int n, int threads, int grain, const F& f) {
  if (threads <= 1 || n <= grain) {
    for (int i = 0; i < n; ++i) f(i);
    return;
  }
  std::atomic<int> next{0};
  auto work = [&] {
    for (;;) {
      const int begin = next.fetch_add(grain);
      if (begin >= n) return;
      const int end = std::min(n, begin + grain);
      for (int i = begin; i < end; ++i) f(i);
    }
  };
  std::vector<std::thread> pool;
  const int helpers = std::min(threads, (n + grain - 1) / grain) - 1;
  for (int t = 0; t < helpers; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
}

}  // namespace locforge::sfm

#endif  // LOCFORGE_PLUGINS_GT_SPLINE_BA_BA_PARALLEL_FOR_H_

// What the DenseVLAD stages share: the vocabulary file name, grey images
// of a dataset, a deterministic parallel loop.
#ifndef LOCFORGE_PLUGINS_GLOBAL_DENSEVLAD_IO_H_
#define LOCFORGE_PLUGINS_GLOBAL_DENSEVLAD_IO_H_

#include <atomic>
#include <exception>
#include <mutex>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <thread>
#include <vector>

#include "image_read.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"

namespace locforge::retrieval {

namespace k = locforge::kapture;

inline constexpr const char* kVocabularyFile = "densevlad_vocabulary.bin";

inline cv::Mat ReadGray(const fs::path& dataset, const std::string& image) {
  return image_io::ReadCameraImage(dataset, image, cv::IMREAD_GRAYSCALE);
}


// Runs fn(i) for i in [0, n) on `threads` threads; results go by index, so the
// outcome does not depend on the thread count.
template <typename Fn>
void ParallelFor(int64_t n, int threads, Fn fn) {
  std::atomic<int64_t> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto worker = [&] {
    for (int64_t i; (i = next++) < n;) {
      try {
        fn(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        next = n;
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::min<int64_t>(threads, n); ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace locforge::retrieval

#endif  // LOCFORGE_PLUGINS_GLOBAL_DENSEVLAD_IO_H_

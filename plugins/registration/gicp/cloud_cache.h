// A bounded LRU cache of preprocessed clouds, so that registering the same
// cloud again (a SLAM registers each keyframe against several others, from
// several guesses) skips its downsampling, KD-tree and covariances.
//
// Keyed by content: a hash of the point array, then an exact comparison of
// the points and of the preprocessing options, so a hit is always the cloud
// that was preprocessed; preprocessing is deterministic, so a cached result
// is bit-identical to a fresh one. Thread-safe: concurrent registrations may
// share one cache; values are shared, immutable, and outlive eviction.
//
// Caches of one process also find each other's live entries (a weak index,
// holding no memory of its own): a SLAM creates one back-end per pass (a
// wide gate, then a narrow final pass; rough checks on coarse clouds) with
// equal preprocessing, and each pass would otherwise build the same KD-tree
// and covariances again.
#ifndef LOCFORGE_PLUGINS_REGISTRATION_GICP_CLOUD_CACHE_H_
#define LOCFORGE_PLUGINS_REGISTRATION_GICP_CLOUD_CACHE_H_

#include <cstdint>
#include <list>
#include <memory>
#include <mutex>

#include "preprocess.h"

namespace locforge::gicp {

// 64-bit hash of the points' bytes and their count.
uint64_t HashPoints(const std::vector<Eigen::Vector3f>& points);

class CloudCache {
 public:
  explicit CloudCache(size_t capacity) : capacity_(capacity) {}  // 0 = off

  // The preprocessing of `cloud` under `o` (now the most recently used), or
  // null when absent or when the cache is off.
  std::shared_ptr<const PreprocessedCloud> Find(const PointCloud& cloud, const PreprocessOptions& o);
  // Keeps `value`, the preprocessing of `cloud` under `o`, as the most recently
  // used entry, evicting the least recently used beyond the capacity. Returns
  // the stored value: an equal one when another thread stored it first.
  std::shared_ptr<const PreprocessedCloud> Insert(const PointCloud& cloud, const PreprocessOptions& o,
                                                  std::shared_ptr<const PreprocessedCloud> value);

  struct Stats {
    uint64_t hits = 0, misses = 0;
    uint64_t shared_hits = 0;  // of the hits: entries found in another live cache
    size_t entries = 0;
  };
  Stats stats() const;

 private:
  struct Entry {
    uint64_t hash;
    PreprocessOptions options;
    std::vector<Eigen::Vector3f> points;  // the input, compared on a hash match
    std::shared_ptr<const PreprocessedCloud> value;

    bool Matches(uint64_t h, const PointCloud& cloud, const PreprocessOptions& o) const;
  };
  // Moves a matching entry to the front and returns its value, else null.
  // Caller holds mutex_.
  std::shared_ptr<const PreprocessedCloud> FindLocked(uint64_t hash, const PointCloud& cloud,
                                                      const PreprocessOptions& o);
  // Keeps `entry` in front (evicting beyond the capacity). Caller holds mutex_.
  void KeepLocked(std::shared_ptr<const Entry> entry);

  const size_t capacity_;
  mutable std::mutex mutex_;
  // Most recently used first; a few dozen at most, searched linearly. Shared
  // with the weak index, which sees an entry as long as some cache keeps it.
  std::list<std::shared_ptr<const Entry>> entries_;
  Stats stats_;
};

}  // namespace locforge::gicp

#endif  // LOCFORGE_PLUGINS_REGISTRATION_GICP_CLOUD_CACHE_H_

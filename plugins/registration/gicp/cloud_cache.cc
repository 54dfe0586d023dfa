#include "cloud_cache.h"

#include <cstring>

namespace locforge::gicp {

uint64_t HashPoints(const std::vector<Eigen::Vector3f>& points) {
  // Multiply-rotate over 8-byte words (FxHash-style), then a final mix: fast,
  // and collisions only cost a comparison, never a wrong hit.
  constexpr uint64_t kMul = 0x9E3779B97F4A7C15ull;
  const size_t bytes = points.size() * sizeof(Eigen::Vector3f);
  const auto* data = reinterpret_cast<const unsigned char*>(points.data());
  uint64_t h = points.size() * kMul;
  size_t i = 0;
  for (; i + 8 <= bytes; i += 8) {
    uint64_t w;
    std::memcpy(&w, data + i, 8);
    h = ((h << 5 | h >> 59) ^ w) * kMul;
  }
  if (i < bytes) {
    uint64_t w = 0;
    std::memcpy(&w, data + i, bytes - i);
    h = ((h << 5 | h >> 59) ^ w) * kMul;
  }
  h ^= h >> 33;
  h *= 0xFF51AFD7ED558CCDull;
  return h ^ (h >> 33);
}

namespace {
// Every live entry of every cache of this process, weakly: an entry dies with
// the last cache that keeps it. Expired slots are dropped as they are met.
struct SharedIndex {
  std::mutex mutex;
  std::list<std::weak_ptr<const void>> entries;
};
SharedIndex& Shared() {
  static SharedIndex* index = new SharedIndex;  // never destroyed: caches may outlive statics
  return *index;
}
}  // namespace

bool CloudCache::Entry::Matches(uint64_t h, const PointCloud& cloud, const PreprocessOptions& o) const {
  if (hash != h || !(options == o) || points.size() != cloud.size()) return false;
  return cloud.empty() ||
         std::memcmp(points.data(), cloud.points.data(), cloud.size() * sizeof(Eigen::Vector3f)) == 0;
}

std::shared_ptr<const PreprocessedCloud> CloudCache::FindLocked(uint64_t hash, const PointCloud& cloud,
                                                                const PreprocessOptions& o) {
  for (auto it = entries_.begin(); it != entries_.end(); ++it) {
    if (!(*it)->Matches(hash, cloud, o)) continue;
    entries_.splice(entries_.begin(), entries_, it);
    return (*it)->value;
  }
  return nullptr;
}

void CloudCache::KeepLocked(std::shared_ptr<const Entry> entry) {
  entries_.push_front(std::move(entry));
  if (entries_.size() > capacity_) entries_.pop_back();
  stats_.entries = entries_.size();
}

std::shared_ptr<const PreprocessedCloud> CloudCache::Find(const PointCloud& cloud, const PreprocessOptions& o) {
  if (capacity_ == 0) return nullptr;
  const uint64_t hash = HashPoints(cloud.points);
  std::lock_guard<std::mutex> lock(mutex_);
  if (auto hit = FindLocked(hash, cloud, o)) {
    ++stats_.hits;
    return hit;
  }
  std::shared_ptr<const Entry> found;
  {
    SharedIndex& index = Shared();
    std::lock_guard<std::mutex> shared_lock(index.mutex);
    for (auto it = index.entries.begin(); it != index.entries.end() && !found;) {
      auto live = std::static_pointer_cast<const Entry>(it->lock());
      if (!live) {
        it = index.entries.erase(it);
        continue;
      }
      if (live->Matches(hash, cloud, o)) found = std::move(live);
      ++it;
    }
  }
  if (!found) {
    ++stats_.misses;
    return nullptr;
  }
  ++stats_.hits;
  ++stats_.shared_hits;
  KeepLocked(found);  // already indexed
  return found->value;
}

std::shared_ptr<const PreprocessedCloud> CloudCache::Insert(const PointCloud& cloud, const PreprocessOptions& o,
                                                            std::shared_ptr<const PreprocessedCloud> value) {
  if (capacity_ == 0) return value;
  const uint64_t hash = HashPoints(cloud.points);
  auto fresh = std::make_shared<const Entry>(Entry{hash, o, cloud.points, std::move(value)});  // built outside the lock
  std::lock_guard<std::mutex> lock(mutex_);
  if (auto stored = FindLocked(hash, cloud, o)) return stored;
  {
    SharedIndex& index = Shared();
    std::lock_guard<std::mutex> shared_lock(index.mutex);
    index.entries.push_back(std::shared_ptr<const void>(fresh));
  }
  KeepLocked(fresh);
  return fresh->value;
}

CloudCache::Stats CloudCache::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

}  // namespace locforge::gicp

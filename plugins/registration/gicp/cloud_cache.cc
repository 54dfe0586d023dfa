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

std::shared_ptr<const PreprocessedCloud> CloudCache::FindLocked(uint64_t hash, const PointCloud& cloud,
                                                                const PreprocessOptions& o) {
  for (auto it = entries_.begin(); it != entries_.end(); ++it) {
    if (it->hash != hash || !(it->options == o) || it->points.size() != cloud.size()) continue;
    if (!cloud.empty() &&
        std::memcmp(it->points.data(), cloud.points.data(), cloud.size() * sizeof(Eigen::Vector3f)) != 0)
      continue;
    entries_.splice(entries_.begin(), entries_, it);
    return it->value;
  }
  return nullptr;
}

std::shared_ptr<const PreprocessedCloud> CloudCache::Find(const PointCloud& cloud, const PreprocessOptions& o) {
  if (capacity_ == 0) return nullptr;
  const uint64_t hash = HashPoints(cloud.points);
  std::lock_guard<std::mutex> lock(mutex_);
  auto hit = FindLocked(hash, cloud, o);
  ++(hit ? stats_.hits : stats_.misses);
  return hit;
}

std::shared_ptr<const PreprocessedCloud> CloudCache::Insert(const PointCloud& cloud, const PreprocessOptions& o,
                                                            std::shared_ptr<const PreprocessedCloud> value) {
  if (capacity_ == 0) return value;
  const uint64_t hash = HashPoints(cloud.points);
  std::list<Entry> fresh;  // built outside the lock
  fresh.push_back(Entry{hash, o, cloud.points, std::move(value)});
  std::lock_guard<std::mutex> lock(mutex_);
  if (auto stored = FindLocked(hash, cloud, o)) return stored;
  entries_.splice(entries_.begin(), fresh);
  if (entries_.size() > capacity_) entries_.pop_back();
  stats_.entries = entries_.size();
  return entries_.front().value;
}

CloudCache::Stats CloudCache::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

}  // namespace locforge::gicp

// The cache of preprocessed clouds: hits, LRU eviction, a content key (a
// cloud changed in one coordinate is a miss), options in the key, values
// bit-identical to a fresh preprocessing, and concurrent use.
#include "gicp/cloud_cache.h"

#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <random>
#include <thread>

namespace locforge::gicp {
namespace {

PointCloud RandomCloud(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-5, 5);
  PointCloud c;
  for (int i = 0; i < n; ++i) c.points.emplace_back(u(rng), u(rng), 0.2f * u(rng));
  return c;
}

const PreprocessOptions kOptions{0.25, 20, 1e-3};

std::shared_ptr<const PreprocessedCloud> Fresh(const PointCloud& c, const PreprocessOptions& o = kOptions,
                                               int threads = 1) {
  return std::make_shared<const PreprocessedCloud>(Preprocess(c, o, threads));
}

template <typename T>
bool SameBytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

// Points, covariances and tree answers, bit for bit.
void ExpectIdentical(const PreprocessedCloud& a, const PreprocessedCloud& b) {
  ASSERT_TRUE(SameBytes(a.points, b.points));
  ASSERT_TRUE(SameBytes(a.covariances, b.covariances));
  ASSERT_EQ(a.tree.order(), b.tree.order());
  std::vector<int> ia, ib;
  std::vector<double> da, db;
  for (size_t i = 0; i < a.points.size(); i += 7) {
    a.tree.KNearest(a.points[i], 20, &ia, &da);
    b.tree.KNearest(b.points[i], 20, &ib, &db);
    ASSERT_EQ(ia, ib);
    ASSERT_EQ(da, db);
  }
}

// Two back-end instances (a SLAM's wide pass and its narrow final pass)
// preprocess each cloud once between them, and nothing outlives both.
TEST(CloudCache, CachesFindEachOthersLiveEntries) {
  const PointCloud a = RandomCloud(2000, 41), b = RandomCloud(2000, 42);
  auto wide = std::make_unique<CloudCache>(4);
  CloudCache narrow(4);
  const auto va = wide->Insert(a, kOptions, Fresh(a));
  EXPECT_EQ(narrow.Find(a, kOptions), va);  // the other cache's object: not preprocessed again
  EXPECT_EQ(narrow.stats().shared_hits, 1u);
  EXPECT_EQ(narrow.Find(a, kOptions), va);  // now its own entry
  EXPECT_EQ(narrow.stats().shared_hits, 1u);
  const PreprocessOptions other{0.5, 20, 1e-3};
  EXPECT_EQ(narrow.Find(a, other), nullptr);  // other options: a miss
  wide->Insert(b, kOptions, Fresh(b));
  wide.reset();                               // b's only cache is gone
  EXPECT_EQ(narrow.Find(b, kOptions), nullptr);
  EXPECT_EQ(narrow.Find(a, kOptions), va);    // a lives on in narrow
  EXPECT_EQ(narrow.stats().misses, 2u);
}

TEST(CloudCache, HitsAndLeastRecentlyUsedEviction) {
  const PointCloud a = RandomCloud(3000, 1), b = RandomCloud(3000, 2), c = RandomCloud(3000, 3),
                   d = RandomCloud(3000, 4);
  CloudCache cache(2);
  EXPECT_EQ(cache.Find(a, kOptions), nullptr);
  const auto va = cache.Insert(a, kOptions, Fresh(a));
  EXPECT_EQ(cache.Find(a, kOptions), va);  // the same object: no recomputation
  const auto vb = cache.Insert(b, kOptions, Fresh(b));
  EXPECT_EQ(cache.Find(a, kOptions), va);  // a is now the most recent, b the least
  cache.Insert(c, kOptions, Fresh(c));     // evicts b
  EXPECT_EQ(cache.Find(b, kOptions), nullptr);
  EXPECT_EQ(cache.Find(a, kOptions), va);
  cache.Insert(d, kOptions, Fresh(d));  // evicts c
  EXPECT_EQ(cache.Find(c, kOptions), nullptr);
  EXPECT_NE(cache.Find(d, kOptions), nullptr);
  EXPECT_EQ(cache.Find(a, kOptions), va);
  const CloudCache::Stats s = cache.stats();
  EXPECT_EQ(s.entries, 2u);
  EXPECT_EQ(s.hits, 5u);
  EXPECT_EQ(s.misses, 3u);
  // An evicted value stays valid for whoever holds it.
  EXPECT_EQ(vb->points.size(), Fresh(b)->points.size());
}

TEST(CloudCache, KeyedByContentAndOptions) {
  const PointCloud a = RandomCloud(3000, 5);
  CloudCache cache(4);
  cache.Insert(a, kOptions, Fresh(a));
  PointCloud copy = a;  // another object, same content: a hit
  EXPECT_NE(cache.Find(copy, kOptions), nullptr);
  PointCloud changed = a;  // same size, one coordinate one float step away: a miss
  changed.points[1234].y() = std::nextafter(changed.points[1234].y(), 10.f);
  EXPECT_EQ(cache.Find(changed, kOptions), nullptr);
  PointCloud shorter = a;
  shorter.points.pop_back();
  EXPECT_EQ(cache.Find(shorter, kOptions), nullptr);
  for (const PreprocessOptions& o : {PreprocessOptions{0.3, 20, 1e-3}, PreprocessOptions{0.25, 10, 1e-3},
                                     PreprocessOptions{0.25, 20, 1e-2}})
    EXPECT_EQ(cache.Find(a, o), nullptr);
  EXPECT_EQ(HashPoints(a.points), HashPoints(copy.points));
  EXPECT_NE(HashPoints(a.points), HashPoints(changed.points));
}

TEST(CloudCache, OffWhenCapacityIsZero) {
  const PointCloud a = RandomCloud(1000, 6);
  CloudCache cache(0);
  const auto v = cache.Insert(a, kOptions, Fresh(a));
  EXPECT_NE(v, nullptr);
  EXPECT_EQ(cache.Find(a, kOptions), nullptr);
  EXPECT_EQ(cache.stats().entries, 0u);
}

TEST(CloudCache, CachedIsBitIdenticalToFreshForAnyThreadCount) {
  const PointCloud a = RandomCloud(20000, 7);
  CloudCache cache(1);
  cache.Insert(a, kOptions, Fresh(a, kOptions, 2));
  const auto cached = cache.Find(a, kOptions);
  ASSERT_NE(cached, nullptr);
  for (int threads : {1, 2, 3}) ExpectIdentical(*cached, *Fresh(a, kOptions, threads));
}

TEST(CloudCache, ConcurrentFindsAndInserts) {
  std::vector<PointCloud> clouds;
  for (uint32_t s = 0; s < 6; ++s) clouds.push_back(RandomCloud(2000, 100 + s));
  std::vector<std::shared_ptr<const PreprocessedCloud>> fresh;
  for (const auto& c : clouds) fresh.push_back(Fresh(c));
  CloudCache cache(4);  // fewer than the clouds: evictions race with finds
  std::vector<std::thread> workers;
  std::vector<int> wrong(4, 0);
  for (int t = 0; t < 4; ++t)
    workers.emplace_back([&, t] {
      for (int round = 0; round < 30; ++round) {
        const size_t i = (round * 7 + t * 3) % clouds.size();
        auto v = cache.Find(clouds[i], kOptions);
        if (!v) v = cache.Insert(clouds[i], kOptions, Fresh(clouds[i]));
        if (!SameBytes(v->covariances, fresh[i]->covariances) || !SameBytes(v->points, fresh[i]->points)) ++wrong[t];
      }
    });
  for (auto& w : workers) w.join();
  for (int t = 0; t < 4; ++t) EXPECT_EQ(wrong[t], 0) << t;
  EXPECT_EQ(cache.stats().hits + cache.stats().misses, 120u);
  EXPECT_LE(cache.stats().entries, 4u);
}

}  // namespace
}  // namespace locforge::gicp

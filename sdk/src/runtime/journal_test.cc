#include "journal.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "locforge/runtime/registry.h"
#include "testing.h"

namespace locforge::runtime {
namespace {

namespace fs = std::filesystem;

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(Journal, WritesReadsAndIgnoresTornLinesOfAnyShard) {
  const fs::path dir = testing::MakeTempDir("lfjournal");
  {
    internal::JournalWriter w(internal::JournalPath(dir, 0, 2));
    w.Append("a");
    w.Append("b");
  }
  EXPECT_EQ(internal::JournalPath(dir, 1, 3).filename(), ".items-done.1-of-3");
  std::ofstream(internal::JournalPath(dir, 1, 3)) << "c\nd\ntor";
  std::ofstream(dir / "unrelated.txt") << "x\n";
  EXPECT_EQ(internal::ReadJournals(dir), (std::set<std::string>{"a", "b", "c", "d"}));
  {
    internal::JournalWriter w(internal::JournalPath(dir, 1, 3));  // cuts "tor"
    w.Append("e");
  }
  EXPECT_EQ(Slurp(internal::JournalPath(dir, 1, 3)), "c\nd\ne\n");
  EXPECT_TRUE(internal::ReadJournals(dir / "missing").empty());
  fs::remove_all(dir);
}

TEST(Shard, IsFnv1a64OfTheItemId) {
  // FNV-1a 64 of "a" is 0xaf63dc4c8601ec8c (published test vector).
  EXPECT_EQ(ShardOfItem("a", 1000), static_cast<int>(0xaf63dc4c8601ec8cull % 1000));
  EXPECT_EQ(ShardOfItem("anything", 1), 0);
  int counts[4] = {0, 0, 0, 0};
  for (int i = 0; i < 4000; ++i) ++counts[ShardOfItem("image_" + std::to_string(i) + ".jpg", 4)];
  for (int c : counts) EXPECT_NEAR(c, 1000, 150);  // roughly balanced
}

}  // namespace
}  // namespace locforge::runtime

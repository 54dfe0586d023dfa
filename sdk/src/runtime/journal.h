// Journals of finished items of a per-item stage: one append-only file per
// shard (`.items-done.<index>-of-<count>`), one item id a line, flushed after
// each item. A run killed mid-write leaves at most a torn last line, which
// readers ignore and the next writer cuts off.
#ifndef LOCFORGE_SDK_SRC_RUNTIME_JOURNAL_H_
#define LOCFORGE_SDK_SRC_RUNTIME_JOURNAL_H_

#include <cstdio>
#include <filesystem>
#include <mutex>
#include <set>
#include <string>

namespace locforge::runtime::internal {

// Every item id recorded in any journal in `dir` (of any shard count).
std::set<std::string> ReadJournals(const std::filesystem::path& dir);

std::filesystem::path JournalPath(const std::filesystem::path& dir, int shard_index,
                                  int shard_count);

class JournalWriter {
 public:
  // Opens (creating) the journal for appending, first cutting a torn last line.
  explicit JournalWriter(const std::filesystem::path& path);
  ~JournalWriter();
  JournalWriter(const JournalWriter&) = delete;
  JournalWriter& operator=(const JournalWriter&) = delete;

  // Thread-safe; throws Error when the write fails.
  void Append(const std::string& item);

 private:
  std::filesystem::path path_;
  std::FILE* file_ = nullptr;
  std::mutex mutex_;
};

}  // namespace locforge::runtime::internal

#endif  // LOCFORGE_SDK_SRC_RUNTIME_JOURNAL_H_

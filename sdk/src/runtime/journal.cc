#include "journal.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "locforge/error.h"

namespace locforge::runtime::internal {

namespace fs = std::filesystem;

namespace {

constexpr const char kPrefix[] = ".items-done.";

// Complete lines only: the text after the last '\n' may be a torn write.
void CollectLines(const std::string& text, std::set<std::string>* out) {
  size_t start = 0;
  while (true) {
    const size_t nl = text.find('\n', start);
    if (nl == std::string::npos) break;
    if (nl > start) out->insert(text.substr(start, nl - start));
    start = nl + 1;
  }
}

}  // namespace

fs::path JournalPath(const fs::path& dir, int shard_index, int shard_count) {
  return dir / (std::string(kPrefix) + std::to_string(shard_index) + "-of-" +
                std::to_string(shard_count));
}

std::set<std::string> ReadJournals(const fs::path& dir) {
  std::set<std::string> done;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return done;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(kPrefix, 0) != 0 || name.find(".tmp") != std::string::npos) continue;
    std::ifstream in(it->path(), std::ios::binary);
    if (!in) throw Error("cannot read journal " + it->path().string());
    std::ostringstream text;
    text << in.rdbuf();
    CollectLines(text.str(), &done);
  }
  return done;
}

JournalWriter::JournalWriter(const fs::path& path) : path_(path) {
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  if (fs::exists(path, ec)) {
    std::string text;
    {
      std::ifstream in(path, std::ios::binary);
      std::ostringstream ss;
      ss << in.rdbuf();
      text = ss.str();
    }
    const size_t keep = text.rfind('\n') == std::string::npos ? 0 : text.rfind('\n') + 1;
    if (keep != text.size()) {
      fs::resize_file(path, keep, ec);
      if (ec) throw Error("cannot repair journal " + path.string() + ": " + ec.message());
    }
  }
  file_ = std::fopen(path.c_str(), "ab");
  if (file_ == nullptr)
    throw Error("cannot open journal " + path.string() + ": " + std::strerror(errno));
}

JournalWriter::~JournalWriter() {
  if (file_) std::fclose(file_);
}

void JournalWriter::Append(const std::string& item) {
  std::lock_guard<std::mutex> lock(mutex_);
  const std::string line = item + "\n";
  if (std::fwrite(line.data(), 1, line.size(), file_) != line.size() || std::fflush(file_) != 0)
    throw Error("cannot write journal " + path_.string() + ": " + std::strerror(errno));
}

}  // namespace locforge::runtime::internal

#include "locforge/fs.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <random>
#include <sstream>

#include "locforge/error.h"

namespace locforge {

fs::path TempSibling(const fs::path& path) {
  static std::atomic<uint64_t> counter{0};
  static const uint64_t salt = std::random_device{}();
  std::ostringstream name;
  name << "." << path.filename().string() << ".tmp-" << ::getpid() << "-" << std::hex
       << (salt ^ counter.fetch_add(1));
  return path.parent_path() / name.str();
}

namespace {

void FsyncPath(const fs::path& p) {
  const int fd = ::open(p.c_str(), O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

void Publish(const fs::path& temp, const fs::path& path) {
  FsyncPath(temp);
  std::error_code ec;
  fs::rename(temp, path, ec);
  if (ec) {
    fs::remove(temp, ec);
    throw Error("cannot write " + path.string() + ": " + ec.message());
  }
}

}  // namespace

void WriteFileAtomic(const fs::path& path, std::string_view content) {
  AtomicFile f(path);
  f.stream().write(content.data(), static_cast<std::streamsize>(content.size()));
  f.Commit();
}

AtomicFile::AtomicFile(fs::path path, bool binary) : path_(std::move(path)) {
  if (path_.has_parent_path()) fs::create_directories(path_.parent_path());
  temp_ = TempSibling(path_);
  out_.open(temp_, binary ? std::ios::binary | std::ios::out : std::ios::out);
  if (!out_) throw Error("cannot create " + temp_.string() + ": " + std::strerror(errno));
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    out_.close();
    std::error_code ec;
    fs::remove(temp_, ec);
  }
}

void AtomicFile::Commit() {
  out_.flush();
  const bool ok = static_cast<bool>(out_);
  out_.close();
  if (!ok) {
    std::error_code ec;
    fs::remove(temp_, ec);
    throw Error("cannot write " + path_.string() + " (disk full?)");
  }
  Publish(temp_, path_);
  committed_ = true;
}

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string(), 0, "", "cannot open file: " + std::string(std::strerror(errno)));
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw InputError(path.string(), 0, "", "read error");
  return ss.str();
}

fs::path SafeJoin(const fs::path& root, const std::string& relative, const std::string& origin) {
  const std::string where = origin.empty() ? root.string() : origin;
  if (relative.empty()) throw InputError(where + ": empty path");
  const fs::path rel(relative);
  if (rel.is_absolute() || relative[0] == '/' || relative[0] == '\\')
    throw InputError(where + ": path '" + relative + "' is absolute; dataset paths must be relative to " +
                     root.string());
  // Lexical check first: no component may climb above the root.
  int depth = 0;
  for (const auto& part : rel) {
    const std::string s = part.string();
    if (s == "..") {
      if (--depth < 0)
        throw InputError(where + ": path '" + relative + "' escapes the dataset root " +
                         root.string());
    } else if (s != "." && !s.empty()) {
      ++depth;
    }
  }
  const fs::path joined = (root / rel).lexically_normal();
  // Then resolve symlinks of what exists: a link must not lead outside either.
  std::error_code ec;
  const fs::path real_root = fs::weakly_canonical(root, ec);
  const fs::path real = fs::weakly_canonical(joined, ec);
  if (!ec && !real_root.empty()) {
    auto p = real.begin();
    for (auto r = real_root.begin(); r != real_root.end(); ++r) {
      if (r->empty()) continue;  // trailing separator
      if (p == real.end() || *p != *r)
        throw InputError(where + ": path '" + relative + "' resolves outside the dataset root " +
                         root.string() + " (through a symbolic link)");
      ++p;
    }
  }
  return joined;
}

}  // namespace locforge

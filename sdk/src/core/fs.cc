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

void LinkOrCopyFile(const fs::path& source_path, const fs::path& target) {
  fs::create_directories(target.parent_path());
  const fs::path temp = TempSibling(target);
  std::error_code ec;
  // link(2) does not follow a symbolic link: a hard link to a relative one
  // would dangle in its new folder, so link (or copy) the file it names.
  fs::path source = source_path;
  if (fs::is_symlink(source, ec)) {
    source = fs::canonical(source, ec);
    if (ec)
      throw Error("cannot link or copy " + source_path.string() + ": its symbolic link does not resolve: " +
                  ec.message());
  }
  ec.clear();
  fs::create_hard_link(source, temp, ec);
  if (ec) {
    ec.clear();
    fs::copy_file(source, temp, fs::copy_options::overwrite_existing, ec);
  }
  if (!ec) fs::rename(temp, target, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(temp, ignored);
    throw Error("cannot link or copy " + source.string() + " to " + target.string() + ": " +
                ec.message());
  }
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
    const std::string why = ec.message();
    fs::remove(temp, ec);
    throw Error("cannot write " + path.string() + ": " + why);
  }
  // The rename itself is durable only once the folder is synced.
  FsyncPath(path.has_parent_path() ? path.parent_path() : fs::path("."));
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
  if (committed_) return;
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

namespace {

// Like fs::canonical, but also follows links whose target does not exist and
// keeps the missing tail of the path. `path` is absolute. Throws
// fs::filesystem_error on a link loop or an unreadable component.
fs::path ResolveSymlinks(const fs::path& path, int* hops) {
  fs::path out = path.root_path();
  for (const auto& part : path.relative_path()) {
    if (part.empty() || part == ".") continue;
    if (part == "..") {
      out = out.parent_path();  // `out` holds no links, so this is the real parent
      continue;
    }
    const fs::path next = out / part;
    std::error_code ec;
    const fs::file_status st = fs::symlink_status(next, ec);
    if (st.type() == fs::file_type::not_found) {
      out = next;
    } else if (ec) {
      throw fs::filesystem_error("cannot inspect", next, ec);
    } else if (fs::is_symlink(st)) {
      if (++*hops > 40)
        throw fs::filesystem_error("too many symbolic links", next,
                                   std::make_error_code(std::errc::too_many_symbolic_link_levels));
      fs::path target = fs::read_symlink(next);
      if (target.is_relative()) target = out / target;
      out = ResolveSymlinks(target, hops);
    } else {
      out = next;
    }
  }
  return out;
}

fs::path ResolveSymlinks(const fs::path& path) {
  int hops = 0;
  return ResolveSymlinks(path, &hops);
}

}  // namespace

fs::path JoinRecordPath(const fs::path& root, const std::string& relative, const std::string& origin) {
  const std::string where = origin.empty() ? root.string() : origin;
  if (relative.empty()) throw InputError(where + ": empty path");
  const fs::path rel(relative);
  if (rel.is_absolute() || relative[0] == '/' || relative[0] == '\\')
    throw InputError(where + ": path '" + relative + "' is absolute; dataset paths must be relative to " +
                     root.string());
  // No component may climb above the root.
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
  return (root / rel).lexically_normal();
}

fs::path SafeJoin(const fs::path& root, const std::string& relative, const std::string& origin) {
  const std::string where = origin.empty() ? root.string() : origin;
  const fs::path joined = JoinRecordPath(root, relative, origin);
  // Then resolve symlinks, dangling ones included (an output written through
  // a dangling link lands at its target): a link must not lead outside either.
  // Fail closed: a path that cannot be resolved (a link loop, no permission)
  // is refused rather than trusted.
  fs::path real_root, real;
  try {
    real_root = ResolveSymlinks(fs::absolute(root));
    real = ResolveSymlinks(fs::absolute(joined));
  } catch (const fs::filesystem_error& e) {
    throw InputError(where + ": cannot resolve path '" + relative + "' under " + root.string() +
                     ": " + e.code().message());
  }
  auto p = real.begin();
  for (auto r = real_root.begin(); r != real_root.end(); ++r) {
    if (r->empty()) continue;  // trailing separator
    if (p == real.end() || *p != *r)
      throw InputError(where + ": path '" + relative + "' resolves outside the dataset root " +
                       root.string() + " (through a symbolic link)");
    ++p;
  }
  return joined;
}

}  // namespace locforge

// File-system helpers every stage needs: atomic writes (temp file + rename,
// so an interrupted run never leaves a corrupt result) and path joins that
// refuse to leave a dataset root.
#ifndef LOCFORGE_FS_H_
#define LOCFORGE_FS_H_

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace locforge {

namespace fs = std::filesystem;

// Writes `content` to `path` atomically: a temp file in the same folder is
// written, flushed, fsync'ed and renamed over `path`. Creates parent folders.
void WriteFileAtomic(const fs::path& path, std::string_view content);

// Publishes `source` at `target` atomically: a hard link when both share a
// file system, else a copy; either way `target` appears only when complete
// (temp sibling + rename) and no temp file is left on failure. Creates parent
// folders; throws Error naming both paths.
void LinkOrCopyFile(const fs::path& source, const fs::path& target);

// Streams a file that appears at `path` only on Commit(); destroyed without
// Commit() (error, exception), it removes the temp file and leaves `path` as
// it was.
class AtomicFile {
 public:
  explicit AtomicFile(fs::path path, bool binary = true);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ofstream& stream() { return out_; }
  void Commit();
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
  fs::path temp_;
  std::ofstream out_;
  bool committed_ = false;
};

// Reads a whole file; throws InputError naming it when it cannot.
std::string ReadFile(const fs::path& path);

// Joins a relative path from a dataset file to its root, refusing absolute
// paths and any path that escapes the root (through "..", or a symlink found
// under the root that points outside it). Throws InputError naming `origin`
// (e.g. "records_camera.txt:12").
fs::path SafeJoin(const fs::path& root, const std::string& relative,
                  const std::string& origin = "");

// Joins a record path of a dataset file (e.g. records_camera.txt) to its
// sensors/records_data folder, refusing only what escapes lexically: an
// absolute path, or one that climbs above the root with "..". Symbolic links
// under the root are followed wherever they lead: they are the dataset
// owner's choice (kapture's importers write records_data as links with
// --image_transfer link_absolute or link_relative). Throws InputError naming
// `origin`.
fs::path JoinRecordPath(const fs::path& root, const std::string& relative,
                        const std::string& origin = "");

// A unique temp name beside `path` (same folder, so rename is atomic).
fs::path TempSibling(const fs::path& path);

}  // namespace locforge

#endif  // LOCFORGE_FS_H_

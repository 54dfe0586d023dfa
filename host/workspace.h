// The workspace on disk: cache keys of nodes, their artifact folders
// (cache/<node>-<key16>/ with a .locforge-complete manifest), the nodes/
// symlinks, per-node locks and the logs/ folder.
#ifndef LOCFORGE_HOST_WORKSPACE_H_
#define LOCFORGE_HOST_WORKSPACE_H_

#include <filesystem>
#include <map>
#include <string>

#include "graph.h"

namespace locforge::host {

namespace fs = std::filesystem;

inline constexpr const char* kCompleteMarker = ".locforge-complete";

// Content stamp of a file or folder: absolute path, and size + mtime of the
// file or of the folder's entries up to depth 2 (at most 10000 of them).
std::string PathStamp(const fs::path& path);

// The text hashed into a node's cache key: stage id, plugin version, SDK
// version, canonical params (not LF_PARAM_NO_CACHE_KEY ones), PATH stamps and
// the keys of the input nodes (`input_keys` maps node name -> key).
std::string CacheKeyText(const ResolvedNode& node,
                         const std::map<std::string, std::string>& input_keys);
// SHA-256 hex of CacheKeyText.
std::string CacheKey(const ResolvedNode& node,
                     const std::map<std::string, std::string>& input_keys);

class Workspace {
 public:
  // Creates the workspace folders (cache/, nodes/, logs/) when missing.
  explicit Workspace(const fs::path& root);

  const fs::path& root() const { return root_; }
  // cache/<node>-<first 16 hex of key>
  fs::path NodeDir(const std::string& node, const std::string& key) const;
  static bool IsComplete(const fs::path& node_dir);
  // nodes/<node>, or variants/<variant>/nodes/<node> in a matrix run.
  fs::path LinkPath(const std::string& variant, const std::string& node) const;
  // Points LinkPath at `node_dir` (relative link, replaced atomically; left
  // untouched when it already points there).
  void Link(const std::string& variant, const std::string& node, const fs::path& node_dir) const;
  // logs/run-<UTC timestamp>.log (unique).
  fs::path NewLogFile() const;

 private:
  fs::path root_;
};

// Writes `manifest` as the completion marker into `partial_dir`, then
// renames it to `node_dir` (an existing `node_dir`, e.g. under --force, is
// moved aside and deleted).
void Publish(const fs::path& partial_dir, const fs::path& node_dir, const std::string& manifest);

// An flock(2) lock on a file beside a node folder; released on destruction.
class FileLock {
 public:
  enum Mode { kShared, kExclusive };
  FileLock(const fs::path& file, Mode mode);  // blocks until granted; throws Error
  ~FileLock();
  FileLock(const FileLock&) = delete;
  FileLock& operator=(const FileLock&) = delete;

 private:
  int fd_ = -1;
};

// Minimal JSON string escaping for manifests.
std::string JsonString(const std::string& s);
// "2026-11-22T04:00:00Z"
std::string UtcNow(bool compact = false);

}  // namespace locforge::host

#endif  // LOCFORGE_HOST_WORKSPACE_H_

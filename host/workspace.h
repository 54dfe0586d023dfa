// The workspace on disk and its node-folder protocol:
//   cache/<node>-<key16>/              a node's artifacts; complete once it holds
//                                      the manifest (kCompleteMarker, JSON)
//   cache/<node>-<key16>.partial       a per-item node in progress: its journals,
//                                      kept so a later run (or shard) resumes
//   cache/<node>-<key16>.partial-<pid> a whole-stage run in progress, private to
//                                      its process (stale once the node lock is held)
//   cache/<node>-<key16>.damaged-<pid> a complete folder found damaged, being
//                                      removed (output_files.h)
//   locks/<node>-<key16>.lock          held while a node is computed (exclusive;
//                                      shared by the shards of a sharded run)
//   locks/<node>-<key16>.shard-I-of-N.lock, .publish.lock
//   nodes/<node> -> ../cache/...       the node's current folder
//   logs/run-<UTC time>.log
//   slurm/                             submissions of `run --executor slurm`
//                                      (host/slurm.h), logs/slurm/ their job logs
// A shard of a per-item node that finished its items leaves a record
// (`.shard-done.I-of-N`, kShardRecordPrefix) in the partial folder: its cost,
// summed into the manifest, and what a re-submission skips.
// A finished node is published by writing its file list (kFileList) and its
// manifest into the partial folder, then renaming that folder to the node's.
#ifndef LOCFORGE_HOST_WORKSPACE_H_
#define LOCFORGE_HOST_WORKSPACE_H_

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "graph.h"

namespace locforge::host {

namespace fs = std::filesystem;

inline constexpr const char* kCompleteMarker = ".locforge-complete";
inline constexpr const char* kShardRecordPrefix = ".shard-done.";
inline constexpr const char* kJournalPrefix = ".items-done.";  // the runtime's (registry.h)
inline constexpr const char* kFileList = ".locforge-files";  // output_files.h

// A node folder's bookkeeping files (manifest, journals, shard records), not
// the stage's outputs.
bool IsProtocolFile(const std::string& file_name);
// Bytes of the stage's outputs in `dir`: regular files at any depth, links
// not followed, protocol files left out.
uint64_t OutputBytes(const fs::path& dir);

// Content stamp of a file or folder: absolute path, and size + mtime of the
// file or of the folder's entries up to depth 2 (at most 10000 of them).
std::string PathStamp(const fs::path& path);

// The text hashed into a node's cache key: stage id, the stage's version (its
// own, else its plugin's), SDK version, canonical params (not
// LF_PARAM_NO_CACHE_KEY ones), PATH stamps, the stage, version and parameter
// values (defaults filled) of each component parameter, and the keys of the input nodes (`input_keys` maps
// node name -> key).
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

  // The folder a run of a node writes into: `.partial` beside `node_dir` for
  // a per-item node (persistent, so it resumes), else `.partial-<pid>`.
  static fs::path PartialDir(const fs::path& node_dir, bool per_item);
  // Removes the `.partial-<pid>` folders of whole-stage runs of `node_dir`:
  // once its node lock is held, any left over is stale (its process died).
  static void RemoveStalePartials(const fs::path& node_dir);
  // locks/<folder name of node_dir><suffix> (".lock", ".publish.lock", ...).
  fs::path LockFile(const fs::path& node_dir, const std::string& suffix) const;

 private:
  fs::path root_;
};

// What a complete node folder records about its run (its kCompleteMarker).
struct Manifest {
  struct Input {
    std::string port, type, path;
  };
  std::string stage;            // kind/name
  std::string plugin, plugin_version, stage_version, plugin_file;
  std::string key;              // full cache key
  std::map<std::string, std::string> params;  // canonical values
  std::vector<Input> inputs;
  std::string finished;         // UTC time
  uint64_t items = 0;           // per-item stages: items processed
  double seconds = 0;           // wall-clock: the run's, or the sum of its shards'
  // Cost, summed over shards (peak: the largest shard's). Manifests of older
  // runs lack them: 0.
  double cpu_seconds = 0;
  uint64_t peak_rss_bytes = 0;
  uint64_t output_bytes = 0;
  int shards = 1;               // processes that computed the items
  std::string started;          // UTC time the (first shard's) run started
  // SHA-256 of the folder's kFileList and its file count (output_files.h).
  // Manifests of older runs lack them: "" (the folder cannot be verified).
  std::string files_sha256;
  uint64_t file_count = 0;
};
std::string FormatManifest(const Manifest& manifest);  // JSON
// Reads the manifest of a complete node folder; throws InputError naming the
// file and field when it is not the JSON FormatManifest writes.
Manifest ReadManifest(const fs::path& node_dir);

// What one shard of a sharded per-item run did, written into the partial
// folder once its items are done (`.shard-done.<index>-of-<count>`, JSON).
struct ShardRecord {
  int index = 0, count = 1;
  uint64_t items = 0;
  double seconds = 0, cpu_seconds = 0;
  uint64_t peak_rss_bytes = 0;
  std::string host, started, finished;
};
fs::path ShardRecordPath(const fs::path& dir, int index, int count);
void WriteShardRecord(const fs::path& dir, const ShardRecord& record);  // atomic
// The records of `dir` for shard count `count` (unreadable ones skipped).
std::vector<ShardRecord> ReadShardRecords(const fs::path& dir, int count);

// Moves a complete node folder found damaged out of the cache (renamed
// aside, then deleted), so that it is computed again. Call with the node's
// lock held.
void DiscardNodeFolder(const fs::path& node_dir);

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

// JSON string escaping (manifests).
std::string JsonString(const std::string& s);
// "2026-11-22T04:00:00Z"
std::string UtcNow(bool compact = false);

}  // namespace locforge::host

#endif  // LOCFORGE_HOST_WORKSPACE_H_

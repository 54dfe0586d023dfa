// The output files of a node folder, recorded when it is published and
// checked before it is served from the cache, so a file deleted, truncated or
// rewritten after the run is never served as the node's result.
//
// .locforge-files (kFileList, beside the manifest) lists every output file,
// one line each: kind ("f" file, "l" symbolic link), size, SHA-256 (of the
// content; of the target text for a link) and path, tab-separated. The
// manifest records the list's SHA-256 and its file count, so the list is
// checked too. It stays a file of its own so that reading a manifest remains
// cheap on nodes of 10^5 files.
//
// Cost: publishing reads every output once to hash it; every run checks
// each served folder by existence, kind and size (a stat per file, the list
// hashed); the contents are hashed again only by `locforge status W
// --verify`, which reads every byte of the workspace.
#ifndef LOCFORGE_HOST_OUTPUT_FILES_H_
#define LOCFORGE_HOST_OUTPUT_FILES_H_

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "progress.h"
#include "workspace.h"

namespace locforge::host {

struct OutputFile {
  std::string path;  // relative to the node folder, '/' separated
  bool link = false;
  uint64_t size = 0;   // 0 for a link
  std::string sha256;  // of the content, or of a link's target text
};

// Every output file under `dir` (links not followed, protocol files left
// out), hashed, sorted by path.
std::vector<OutputFile> ListOutputFiles(const fs::path& dir);
std::string FormatFileList(const std::vector<OutputFile>& files);
// Throws InputError naming `origin` and the line.
std::vector<OutputFile> ParseFileList(const std::string& text, const std::string& origin);

// Writes the file list of `dir` (atomically) and records its hash and count
// in `manifest`: call on the partial folder just before Publish.
void RecordOutputFiles(const fs::path& dir, Manifest* manifest);

struct FolderCheck {
  // False when the manifest predates file lists: nothing to check against.
  bool verifiable = true;
  std::vector<std::string> damage;  // "keypoints/a.kpt: missing", one per file
  uint64_t files = 0;               // files checked
  uint64_t bytes_hashed = 0;
  bool ok() const { return damage.empty(); }
};

// Checks a complete node folder against its list: existence, kind, size and,
// with `hash_contents`, the SHA-256 of every file. Never throws: an
// unreadable manifest or list is damage.
FolderCheck CheckNodeFolder(const fs::path& dir, bool hash_contents);

// Whether the folder `dir` of node `label` is complete and as its run left it
// (sizes checked, not contents). A damaged one is reported as a warning
// naming the node and its files, and discarded, so that the node is computed
// again instead of served; one whose manifest lists no files (an older run's)
// is served, noted in the log.
bool ServableFromCache(const Workspace& workspace, const std::string& label, const fs::path& dir,
                       Reporter& reporter);

// The damage in one line: the first few files, then how many more.
std::string DamageText(const FolderCheck& check);

}  // namespace locforge::host

#endif  // LOCFORGE_HOST_OUTPUT_FILES_H_

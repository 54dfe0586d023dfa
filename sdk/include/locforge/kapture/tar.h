// Tar-packed feature files of kapture 1.1 (kapture/io/tar.py): a type folder
// may hold its per-image files in one archive, e.g.
// reconstruction/keypoints/<type>/keypoints.tar holding "<image>.kpt", or
// reconstruction/matches/<type>/matches.tar holding
// "<image1>.overlapping/<image2>.matches".
//
// TarArchive is a small, strict reader of POSIX ustar archives (what
// Python's tarfile writes; GNU "ustar  " headers, pax extended headers
// with `path` / `size` and GNU long names are read too). It indexes the
// regular files once (name, offset, size) and reads an entry on demand.
// Refused with InputError naming the archive and the entry: a bad header
// checksum or magic, a size that runs past the end of the archive, links,
// devices and FIFOs, and names that could escape the folder (absolute,
// "..", empty components, backslashes, NUL). Folders are skipped. A name
// stored twice reads as its last copy, as the toolbox's TarHandler does
// (its append mode adds a new copy).
#ifndef LOCFORGE_KAPTURE_TAR_H_
#define LOCFORGE_KAPTURE_TAR_H_

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "locforge/fs.h"

namespace locforge::kapture {

struct TarEntry {
  std::string name;     // '/' separated, relative, "./" prefix dropped
  uint64_t offset = 0;  // of the data in the archive
  uint64_t size = 0;
};

class TarArchive {
 public:
  // Indexes `path`; `display_name` is what errors call it (empty: the path).
  explicit TarArchive(const fs::path& path, const std::string& display_name = "");

  const fs::path& path() const { return path_; }
  const std::string& name() const { return name_; }
  // Regular files by name.
  const std::map<std::string, TarEntry>& entries() const { return entries_; }
  const TarEntry* Find(const std::string& name) const;
  // The bytes of one entry; InputError when the archive changed under us.
  std::vector<uint8_t> Read(const TarEntry& entry) const;

 private:
  fs::path path_;
  std::string name_;
  std::map<std::string, TarEntry> entries_;
};

// The archive of a matches type folder; a feature type folder's is
// "<kind>.tar" (TarName in kapture.h's layout).
inline constexpr const char* kMatchesTarName = "matches.tar";

}  // namespace locforge::kapture

#endif  // LOCFORGE_KAPTURE_TAR_H_

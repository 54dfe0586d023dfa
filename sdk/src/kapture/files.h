// File helpers shared by the parts of the kapture library (reader, writers,
// copy, inspection). Internal: not installed.
#ifndef LOCFORGE_SDK_SRC_KAPTURE_FILES_H_
#define LOCFORGE_SDK_SRC_KAPTURE_FILES_H_

#include <algorithm>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"

namespace locforge::kapture::files {

inline constexpr FeatureKind kAllKinds[] = {FeatureKind::kKeypoints, FeatureKind::kDescriptors,
                                 FeatureKind::kGlobalFeatures};

inline std::string InfoFileName(FeatureKind kind) { return std::string(FeatureKindFolder(kind)) + ".txt"; }

inline bool IsDir(const fs::path& p) {
  std::error_code ec;
  return fs::is_directory(p, ec);
}
inline bool IsFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

inline bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

inline std::string Rel(const fs::path& p, const fs::path& base) {
  return p.lexically_relative(base).generic_string();
}

// Regular files under `dir` (symlinks to files included), sorted by path.
inline std::vector<fs::path> FilesUnder(const fs::path& dir) {
  std::vector<fs::path> files;
  if (!IsDir(dir)) return files;
  for (auto it = fs::recursive_directory_iterator(dir); it != fs::recursive_directory_iterator();
       ++it) {
    std::error_code ec;
    if (it->is_regular_file(ec)) files.push_back(it->path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

inline FeatureSet MakeFeatureSet(FeatureKind kind, const std::string& type, const fs::path& dir,
                          const std::string& display_dir, bool legacy) {
  FeatureSet set;
  set.kind = kind;
  set.dir = dir;
  set.legacy_layout = legacy;
  set.info = ReadFeatureInfo(dir / InfoFileName(kind), kind, display_dir + "/" + InfoFileName(kind));
  set.type = type.empty() ? set.info.name : type;
  const std::string tar = layout::FeatureTarName(kind);
  if (IsFile(dir / tar))
    set.archive = std::make_shared<const TarArchive>(dir / tar, display_dir + "/" + tar);
  return set;
}

// The archive entry of one image of a tar-packed set, or null.
inline const TarEntry* ArchiveEntry(const FeatureSet& set, const std::string& image) {
  return set.archive ? set.archive->Find(image + FeatureKindExtension(set.kind)) : nullptr;
}

// True when the set has a file for `image`, loose or in its archive.
inline bool SetHasImage(const FeatureSet& set, const std::string& image) {
  return IsFile(set.dir / (image + FeatureKindExtension(set.kind))) || ArchiveEntry(set, image);
}

// What errors call an archive entry: "<archive>: entry '<name>'".
inline std::string EntryName(const TarArchive& archive, const std::string& entry) {
  return archive.name() + ": entry '" + entry + "'";
}

// Record types whose records point at files under records_data.
inline bool IsDataRecordType(const std::string& type) {
  const RecordKind k = RecordKindOf(type);
  return k == RecordKind::kCamera || k == RecordKind::kLidar || k == RecordKind::kDepth;
}

// Shared by copy and export (copy.cc).
fs::path Canonical(const fs::path& p);
bool IsWithin(const fs::path& inner, const fs::path& outer);
// Refuses (InputError) a destination equal to, inside or containing `src`,
// a non-folder, and a non-empty folder unless `overwrite`.
void CheckDestination(const fs::path& src, const fs::path& dst, bool overwrite);
// Copies a file byte for byte, atomically.
void CopyVerbatim(const fs::path& from, const fs::path& to);
// Reads a feature or matches file checked against dtype/dsize and writes
// its bytes to `to`.
void RewriteFeatureFile(const fs::path& from, const fs::path& to, DType dtype, int64_t dsize,
                        const std::string& display);
// Streams records_<type>.txt from `from` to `to` in the toolbox's format;
// returns the number of records.
int64_t CopyRecordsFile(const fs::path& from, const fs::path& to, const std::string& type,
                        const std::string& display, const fs::path& data_root);

}  // namespace locforge::kapture::files

#endif  // LOCFORGE_SDK_SRC_KAPTURE_FILES_H_

// Copying a kapture dataset: CopyKapture, CopyFeatureFolder (kapture.h).
#include "locforge/kapture/kapture.h"

#include <algorithm>
#include <map>
#include <set>

#include "files.h"
#include "locforge/error.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/rigs.h"

namespace locforge::kapture {

using namespace files;  // NOLINT: the library's own helpers

// ------------------------------------------------------------------- copy

bool CopyOptions::Check(std::string* why) const {
  (void)why;
  return true;
}

namespace files {

fs::path Canonical(const fs::path& p) {
  std::error_code ec;
  fs::path c = fs::weakly_canonical(fs::absolute(p), ec);
  return ec ? fs::absolute(p).lexically_normal() : c;
}

bool IsWithin(const fs::path& inner, const fs::path& outer) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o) {
    if (o->empty()) continue;
    if (i == inner.end() || *i != *o) return false;
    ++i;
  }
  return true;
}

void CheckDestination(const fs::path& src, const fs::path& dst, bool overwrite) {
  const fs::path s = Canonical(src);
  const fs::path d = Canonical(dst);
  if (IsWithin(d, s))
    throw InputError(dst.string(), 0, "",
                     "destination is the source or inside it (" + src.string() +
                         "); refusing to write into the source");
  if (IsWithin(s, d))
    throw InputError(dst.string(), 0, "",
                     "destination contains the source (" + src.string() + "); refusing");
  std::error_code ec;
  if (fs::exists(dst, ec)) {
    if (!IsDir(dst)) throw InputError(dst.string(), 0, "", "exists and is not a folder");
    if (!overwrite && !fs::is_empty(dst, ec))
      throw InputError(dst.string(), 0, "",
                       "exists and is not empty (set overwrite; --overwrite on the command line)");
  }
}

void CopyVerbatim(const fs::path& from, const fs::path& to) {
  AtomicFile out(to, true);
  std::ifstream in(from, std::ios::binary);
  if (!in) throw InputError(from.string(), 0, "", "cannot open file");
  // `<< rdbuf()` of an empty file inserts nothing and fails the stream.
  std::error_code ec;
  if (fs::file_size(from, ec) > 0 || ec) out.stream() << in.rdbuf();
  if (in.bad()) throw InputError(from.string(), 0, "", "read error");
  out.Commit();
}

void RewriteFeatureFile(const fs::path& from, const fs::path& to, DType dtype, int64_t dsize,
                        const std::string& display) {
  WriteFeatureFile(to, ReadFeatureFile(from, dtype, dsize, display));
}

}  // namespace files

namespace {

// Writes the entries of an archive as loose files beside `to`, feature
// files checked (a loose file of the source with the same name wins, as it
// does when reading). Returns the number of files written.
int64_t UnpackArchive(const TarArchive& archive, const fs::path& from, const fs::path& to,
                      const std::string& ext, DType dtype, int64_t dsize) {
  int64_t n = 0;
  for (const auto& [name, entry] : archive.entries()) {
    if (IsFile(from.parent_path() / name)) continue;
    const fs::path out = SafeJoin(to.parent_path(), name, EntryName(archive, name));
    std::vector<uint8_t> bytes = archive.Read(entry);
    if (EndsWith(name, ext))
      WriteFeatureFile(out, FeatureArrayFromBytes(std::move(bytes), dtype, dsize,
                                                  EntryName(archive, name)));
    else
      WriteFileAtomic(out, std::string_view(reinterpret_cast<const char*>(bytes.data()),
                                            bytes.size()));
    ++n;
  }
  return n;
}

// Every entry of an archive with `ext` holds whole rows of dtype x dsize;
// then the archive is copied byte for byte (kept packed), or unpacked.
// Returns the number of files written.
int64_t CopyArchive(const fs::path& from, const fs::path& to, const std::string& ext, DType dtype,
                    int64_t dsize, const std::string& display, bool unpack) {
  const TarArchive archive(from, display);
  if (unpack) return UnpackArchive(archive, from, to, ext, dtype, dsize);
  const uint64_t row_bytes = static_cast<uint64_t>(dsize) * DTypeSize(dtype);
  for (const auto& [name, entry] : archive.entries())
    if (EndsWith(name, ext) && entry.size % row_bytes != 0)
      throw InputError(EntryName(archive, name), 0, "",
                       "size " + std::to_string(entry.size) + " bytes is not a multiple of " +
                           std::to_string(row_bytes) + " (dsize " + std::to_string(dsize) +
                           " x sizeof(" + DTypeName(dtype) + "))");
  CopyVerbatim(from, to);
  return 1;
}

}  // namespace

namespace files {

template <class Record>
int64_t CopyRecords(const fs::path& from, const fs::path& to, RecordKind kind,
                    const std::string& display, const fs::path& data_root) {
  RecordsReader<Record> reader(from, display, data_root);
  Record r;
  // The generic kind keeps the source's column comment; it is read lazily,
  // so take it once the first record (and the comments before it) is read.
  std::unique_ptr<RecordsWriter<Record>> writer;
  int64_t n = 0;
  bool more = reader.Next(&r);
  writer = std::make_unique<RecordsWriter<Record>>(
      to, kind, kind == RecordKind::kGeneric ? reader.ColumnsComment() : "");
  while (more) {
    writer->Write(r);
    ++n;
    more = reader.Next(&r);
  }
  writer->Commit();
  return n;
}

int64_t CopyRecordsFile(const fs::path& from, const fs::path& to, const std::string& type,
                        const std::string& display, const fs::path& data_root) {
  const RecordKind kind = RecordKindOf(type);
  switch (kind) {
    case RecordKind::kCamera:
    case RecordKind::kLidar:
    case RecordKind::kDepth: return CopyRecords<DataRecord>(from, to, kind, display, data_root);
    case RecordKind::kGnss: return CopyRecords<GnssRecord>(from, to, kind, display, data_root);
    case RecordKind::kWifi: return CopyRecords<WifiRecord>(from, to, kind, display, data_root);
    case RecordKind::kBluetooth:
      return CopyRecords<BluetoothRecord>(from, to, kind, display, data_root);
    case RecordKind::kAccelerometer:
    case RecordKind::kGyroscope:
    case RecordKind::kMagnetic:
      return CopyRecords<Vector3Record>(from, to, kind, display, data_root);
    case RecordKind::kGeneric: return CopyRecords<GenericRecord>(from, to, kind, display, data_root);
  }
  return 0;
}

}  // namespace files

namespace {

constexpr size_t kListCap = 100;

// reconstruction/matches/<type>/matches.tar (or matches/matches.tar for
// the 1.0 layout's single type).
bool IsMatchesArchive(const std::string& rel, const std::vector<std::string>& match_types) {
  const std::string base = std::string(layout::kMatches) + "/";
  if (rel == base + kMatchesTarName) return true;
  for (const std::string& type : match_types)
    if (rel == base + type + "/" + kMatchesTarName) return true;
  return false;
}

// One copy: the source's feature folders (1.1 per type or 1.0 single) and
// match types, and the report.
struct Copier {
  Copier(const fs::path& src, const fs::path& dst, const CopyOptions& options)
      : k(src), src(src), dst(dst), options(options), data_root(src / layout::kRecordsData) {}

  Kapture k;
  const fs::path& src;
  const fs::path& dst;
  const CopyOptions& options;
  const fs::path data_root;
  CopyReport report;
  std::vector<FeatureSet> sets;
  std::vector<std::string> match_types;

  void ReadStructure() {
    for (FeatureKind kind : kAllKinds)
      for (FeatureSet& s : k.FeatureSets(kind)) sets.push_back(std::move(s));
    match_types = k.MatchesTypes();
    k.observations();  // validates before anything is written
    k.points3d();
  }

  // The kapture's text files, rewritten from what was read: false for other files.
  bool CopyTextFile(const fs::path& file, const std::string& rel, const fs::path& out) {
    if (rel == layout::kSensors) {
      WriteSensors(out, k.sensors());
    } else if (rel == layout::kRigs) {
      WriteRigs(out, k.rigs());
    } else if (rel == layout::kTrajectories) {
      WriteTrajectories(out, k.trajectories());
    } else if (rel.rfind("sensors/records_", 0) == 0 && EndsWith(rel, ".txt") &&
               rel.find('/', 8) == std::string::npos) {
      const std::string type = rel.substr(16, rel.size() - 20);
      report.records += CopyRecordsFile(file, out, type, rel, data_root);
    } else if (rel == layout::kPoints3d) {
      WritePoints3d(out, k.points3d());
    } else if (rel == layout::kObservations) {
      WriteObservations(out, k.observations());
    } else {
      return false;
    }
    ++report.text_files;
    return true;
  }

  // The deepest feature folder holding rel (null: none).
  const FeatureSet* OwnerOf(const std::string& rel) const {
    const FeatureSet* owner = nullptr;
    for (const FeatureSet& s : sets) {
      const std::string dir = Rel(s.dir, src) + "/";
      if (rel.rfind(dir, 0) == 0 && (!owner || Rel(s.dir, src).size() > Rel(owner->dir, src).size())) owner = &s;
    }
    return owner;
  }

  // Feature and match files and archives, checked and rewritten; anything else verbatim.
  void CopyFeatureOrOther(const fs::path& file, const std::string& rel, const fs::path& out) {
    const FeatureSet* owner = OwnerOf(rel);
    const fs::path parent = file.parent_path();
    const std::string ext = owner ? FeatureKindExtension(owner->kind) : "";
    if (owner && parent == owner->dir && file.filename() == InfoFileName(owner->kind)) {
      WriteFeatureInfo(out, owner->info);
      ++report.text_files;
    } else if (owner && EndsWith(rel, ext)) {
      RewriteFeatureFile(file, out, owner->info.dtype, owner->info.dsize, rel);
      ++report.binary_files;
    } else if (owner && parent == owner->dir && owner->archive &&
               file.filename() == layout::FeatureTarName(owner->kind)) {
      report.binary_files +=
          CopyArchive(file, out, ext, owner->info.dtype, owner->info.dsize, rel, options.unpack_archives);
    } else if (rel.rfind(std::string(layout::kMatches) + "/", 0) == 0 && EndsWith(rel, ".matches")) {
      RewriteFeatureFile(file, out, DType::kFloat64, 3, rel);
      ++report.binary_files;
    } else if (IsMatchesArchive(rel, match_types)) {
      report.binary_files += CopyArchive(file, out, ".matches", DType::kFloat64, 3, rel, options.unpack_archives);
    } else {
      CopyVerbatim(file, out);
      ++report.other_files;
      report.notes.push_back("copied verbatim (not a kapture file): " + rel);
    }
  }

  void CopyFile(const fs::path& file) {
    const std::string rel = Rel(file, src);
    // A link may not lead out of the dataset, except under records_data,
    // where links are the owner's choice (kapture's link imports): the
    // copy holds the files they name.
    std::error_code ec;
    const bool in_records_data = rel.rfind(std::string(layout::kRecordsData) + "/", 0) == 0;
    if (!in_records_data && fs::is_symlink(file, ec)) SafeJoin(src, rel, rel);
    const fs::path out = dst / rel;
    if (CopyTextFile(file, rel, out)) return;
    if (in_records_data) {
      if (options.copy_records_data) {
        CopyVerbatim(file, out);
        ++report.data_files;
      }
      return;
    }
    CopyFeatureOrOther(file, rel, out);
  }

  // Records naming files absent from the source: listed, not fatal.
  void ListMissingDataFiles() {
    int64_t missing = 0;
    for (const std::string& type : k.RecordTypes()) {
      if (!IsDataRecordType(type)) continue;
      auto reader = k.StreamRecords<DataRecord>(type);
      DataRecord r;
      while (reader.Next(&r)) {
        if (IsFile(data_root / r.path)) continue;
        if (report.missing_data_files.size() < kListCap)
          report.missing_data_files.push_back(std::string(layout::kRecordsData) + "/" + r.path);
        ++missing;
      }
    }
    if (missing > static_cast<int64_t>(report.missing_data_files.size()))
      report.notes.push_back(std::to_string(missing) + " record files are missing in the source (" +
                             std::to_string(report.missing_data_files.size()) + " listed)");
  }
};

}  // namespace

CopyReport CopyKapture(const fs::path& src, const fs::path& dst, const CopyOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw ParamError("copy options: " + why);
  Copier c(src, dst, options);
  CheckDestination(src, dst, options.overwrite);
  c.ReadStructure();
  // Walked, not listed: a dataset of 100k images must not be held in memory.
  for (auto it = fs::recursive_directory_iterator(src); it != fs::recursive_directory_iterator(); ++it) {
    std::error_code type_ec;
    if (!it->is_regular_file(type_ec)) continue;
    c.CopyFile(it->path());
  }
  c.ListMissingDataFiles();
  return std::move(c.report);
}

int64_t CopyFeatureFolder(FeatureKind kind, const fs::path& src, const fs::path& dst,
                          bool overwrite) {
  if (!IsDir(src)) throw InputError(src.string(), 0, "", "not a folder");
  CheckDestination(src, dst, overwrite);
  const FeatureInfo info = ReadFeatureInfo(src / InfoFileName(kind), kind,
                                           (src / InfoFileName(kind)).string());
  const std::string ext = FeatureKindExtension(kind);
  int64_t n = 0;
  for (const fs::path& file : FilesUnder(src)) {
    const std::string rel = Rel(file, src);
    std::error_code ec;
    if (fs::is_symlink(file, ec)) SafeJoin(src, rel, rel);
    if (rel == InfoFileName(kind)) {
      WriteFeatureInfo(dst / rel, info);
    } else if (EndsWith(rel, ext)) {
      RewriteFeatureFile(file, dst / rel, info.dtype, info.dsize, file.string());
      ++n;
    } else {
      CopyVerbatim(file, dst / rel);
    }
  }
  return n;
}

}  // namespace locforge::kapture

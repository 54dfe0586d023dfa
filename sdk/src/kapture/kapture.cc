#include "locforge/kapture/kapture.h"

#include <algorithm>
#include <set>

#include "locforge/error.h"
#include "locforge/kapture/rigs.h"

namespace locforge::kapture {

namespace layout {
std::string RecordsFile(const std::string& sensor_type) {
  return "sensors/records_" + sensor_type + ".txt";
}
std::string FeatureRoot(FeatureKind kind) {
  return std::string("reconstruction/") + FeatureKindFolder(kind);
}
std::string MatchesFile(const std::string& image1, const std::string& image2) {
  return image1 + ".overlapping/" + image2 + ".matches";
}
}  // namespace layout

namespace {

const FeatureKind kAllKinds[] = {FeatureKind::kKeypoints, FeatureKind::kDescriptors,
                                 FeatureKind::kGlobalFeatures};

std::string InfoFileName(FeatureKind kind) { return std::string(FeatureKindFolder(kind)) + ".txt"; }

bool IsDir(const fs::path& p) {
  std::error_code ec;
  return fs::is_directory(p, ec);
}
bool IsFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string Rel(const fs::path& p, const fs::path& base) {
  return p.lexically_relative(base).generic_string();
}

// Regular files under `dir` (symlinks to files included), sorted by path.
std::vector<fs::path> FilesUnder(const fs::path& dir) {
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

FeatureSet MakeFeatureSet(FeatureKind kind, const std::string& type, const fs::path& dir,
                          const std::string& display_dir, bool legacy) {
  FeatureSet set;
  set.kind = kind;
  set.dir = dir;
  set.legacy_layout = legacy;
  set.info = ReadFeatureInfo(dir / InfoFileName(kind), kind, display_dir + "/" + InfoFileName(kind));
  set.type = type.empty() ? set.info.name : type;
  return set;
}

}  // namespace

struct Kapture::Cache {
  std::optional<Sensors> sensors;
  std::optional<Rigs> rigs;
  std::optional<Trajectories> trajectories;
  std::optional<std::vector<Point3d>> points3d;
  std::optional<Observations> observations;
  bool features_scanned = false;
  std::map<std::pair<FeatureKind, std::string>, FeatureSet> features;
  std::map<std::pair<FeatureKind, std::string>, FeatureSet> attached;
  std::string legacy_keypoints_type;  // set when reconstruction/keypoints is 1.0 style
};

Kapture::Kapture(fs::path root) : root_(std::move(root)), cache_(std::make_unique<Cache>()) {
  if (!IsDir(root_)) throw InputError(root_.string(), 0, "", "not a folder (expected a kapture root)");
}
Kapture::~Kapture() = default;
Kapture::Kapture(Kapture&&) noexcept = default;
Kapture& Kapture::operator=(Kapture&&) noexcept = default;

const Sensors& Kapture::sensors() const {
  if (!cache_->sensors) {
    const fs::path p = root_ / layout::kSensors;
    cache_->sensors = IsFile(p) ? ReadSensors(p, layout::kSensors) : Sensors();
  }
  return *cache_->sensors;
}

const Rigs& Kapture::rigs() const {
  if (!cache_->rigs) {
    const fs::path p = root_ / layout::kRigs;
    cache_->rigs = IsFile(p) ? ReadRigs(p, layout::kRigs) : Rigs();
  }
  return *cache_->rigs;
}

const Trajectories& Kapture::trajectories() const {
  if (!cache_->trajectories) {
    const fs::path p = root_ / layout::kTrajectories;
    cache_->trajectories = IsFile(p) ? ReadTrajectories(p, layout::kTrajectories) : Trajectories();
  }
  return *cache_->trajectories;
}

std::optional<Pose> Kapture::DevicePose(Timestamp timestamp, const std::string& device_id) const {
  return kapture::DevicePose(trajectories(), rigs(), timestamp, device_id);
}

std::vector<std::string> Kapture::RecordTypes() const {
  std::vector<std::string> types;
  const fs::path dir = root_ / "sensors";
  if (!IsDir(dir)) return types;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("records_", 0) == 0 && EndsWith(name, ".txt") && name.size() > 12 &&
        IsFile(entry.path()))
      types.push_back(name.substr(8, name.size() - 12));
  }
  std::sort(types.begin(), types.end());
  return types;
}

bool Kapture::HasRecords(const std::string& sensor_type) const {
  return IsFile(root_ / layout::RecordsFile(sensor_type));
}

std::vector<DataRecord> Kapture::ReadDataRecords(const std::string& sensor_type) const {
  std::vector<DataRecord> out;
  ForEachDataRecord(sensor_type, [&](const DataRecord& r) { out.push_back(r); });
  return out;
}

void Kapture::ForEachDataRecord(const std::string& sensor_type,
                                const std::function<void(const DataRecord&)>& fn) const {
  auto reader = StreamRecords<DataRecord>(sensor_type);
  DataRecord r;
  while (reader.Next(&r)) fn(r);
}

std::vector<std::string> Kapture::CameraImages() const {
  std::set<std::string> images;
  ForEachDataRecord("camera", [&](const DataRecord& r) { images.insert(r.path); });
  return {images.begin(), images.end()};
}

fs::path Kapture::RecordDataPath(const std::string& relative, const std::string& origin) const {
  return SafeJoin(root_ / layout::kRecordsData, relative,
                  origin.empty() ? std::string(layout::kRecordsData) : origin);
}

fs::path Kapture::ExistingRecordDataPath(const std::string& relative,
                                         const std::string& origin) const {
  const fs::path p = RecordDataPath(relative, origin);
  if (!IsFile(p))
    throw InputError((origin.empty() ? std::string(layout::kRecordsData) : origin) +
                     ": missing file '" + relative + "' (looked for " + p.string() + ")");
  return p;
}

void Kapture::ScanFeatures() const {
  if (cache_->features_scanned) return;
  for (FeatureKind kind : kAllKinds) {
    const std::string display = layout::FeatureRoot(kind);
    const fs::path dir = root_ / display;
    if (!IsDir(dir)) continue;
    if (IsFile(dir / InfoFileName(kind))) {
      // kapture 1.0: one type, the folder itself.
      FeatureSet set = MakeFeatureSet(kind, "", dir, display, true);
      if (kind == FeatureKind::kKeypoints) cache_->legacy_keypoints_type = set.type;
      cache_->features[{kind, set.type}] = std::move(set);
      continue;
    }
    for (const auto& entry : fs::directory_iterator(dir)) {
      if (!IsDir(entry.path()) || !IsFile(entry.path() / InfoFileName(kind))) continue;
      const std::string type = entry.path().filename().string();
      cache_->features[{kind, type}] =
          MakeFeatureSet(kind, type, entry.path(), display + "/" + type, false);
    }
  }
  cache_->features_scanned = true;
}

std::vector<FeatureSet> Kapture::FeatureSets(FeatureKind kind) const {
  ScanFeatures();
  std::vector<FeatureSet> out;
  for (const auto* m : {&cache_->features, &cache_->attached})
    for (const auto& [key, set] : *m)
      if (key.first == kind) out.push_back(set);
  return out;
}

const FeatureSet& Kapture::GetFeatureSet(FeatureKind kind, const std::string& type) const {
  ScanFeatures();
  auto it = cache_->attached.find({kind, type});
  if (it != cache_->attached.end()) return it->second;
  it = cache_->features.find({kind, type});
  if (it != cache_->features.end()) return it->second;
  std::string known;
  for (const auto& s : FeatureSets(kind)) known += (known.empty() ? "" : ", ") + s.type;
  throw InputError(root_.string(), 0, "",
                   std::string("no ") + FeatureKindFolder(kind) + " of type '" + type +
                       "' (present: " + (known.empty() ? "none" : known) + ")");
}

bool Kapture::HasFeatureType(FeatureKind kind, const std::string& type) const {
  ScanFeatures();
  return cache_->attached.count({kind, type}) || cache_->features.count({kind, type});
}

void Kapture::AttachFeatures(FeatureKind kind, const std::string& type, const fs::path& dir) {
  if (!IsFile(dir / InfoFileName(kind)))
    throw InputError(dir.string(), 0, "", "no " + InfoFileName(kind) + " in this folder");
  cache_->attached[{kind, type}] = MakeFeatureSet(kind, type, dir, dir.string(), false);
}

fs::path Kapture::FeatureFile(FeatureKind kind, const std::string& type,
                              const std::string& image) const {
  const FeatureSet& set = GetFeatureSet(kind, type);
  return SafeJoin(set.dir, image + FeatureKindExtension(kind),
                  Rel(set.dir, root_) + "/" + image + FeatureKindExtension(kind));
}

bool Kapture::HasFeatureFile(FeatureKind kind, const std::string& type,
                             const std::string& image) const {
  return IsFile(FeatureFile(kind, type, image));
}

FeatureArray Kapture::ReadFeatures(FeatureKind kind, const std::string& type,
                                   const std::string& image) const {
  const FeatureSet& set = GetFeatureSet(kind, type);
  const fs::path p = FeatureFile(kind, type, image);
  return ReadFeatureFile(p, set.info.dtype, set.info.dsize, p.string());
}

std::vector<std::string> Kapture::FeatureImages(FeatureKind kind, const std::string& type) const {
  const FeatureSet& set = GetFeatureSet(kind, type);
  const std::string ext = FeatureKindExtension(kind);
  std::vector<std::string> images;
  for (const fs::path& f : FilesUnder(set.dir)) {
    const std::string rel = Rel(f, set.dir);
    if (EndsWith(rel, ext)) images.push_back(rel.substr(0, rel.size() - ext.size()));
  }
  return images;
}

namespace {
fs::path MatchesDirOf(const fs::path& root, const std::string& legacy_type,
                      const std::string& type) {
  const fs::path base = root / layout::kMatches;
  return (!legacy_type.empty() && type == legacy_type) ? base : base / type;
}
}  // namespace

std::vector<std::string> Kapture::MatchesTypes() const {
  ScanFeatures();
  std::vector<std::string> types;
  const fs::path dir = root_ / layout::kMatches;
  if (!IsDir(dir)) return types;
  if (!cache_->legacy_keypoints_type.empty()) return {cache_->legacy_keypoints_type};
  for (const auto& entry : fs::directory_iterator(dir))
    if (IsDir(entry.path())) types.push_back(entry.path().filename().string());
  std::sort(types.begin(), types.end());
  return types;
}

std::vector<std::pair<std::string, std::string>> Kapture::MatchPairs(
    const std::string& keypoints_type) const {
  ScanFeatures();
  const fs::path dir = MatchesDirOf(root_, cache_->legacy_keypoints_type, keypoints_type);
  std::vector<std::pair<std::string, std::string>> pairs;
  for (const fs::path& f : FilesUnder(dir)) {
    std::string rel = Rel(f, dir);
    if (!EndsWith(rel, ".matches")) continue;
    rel.resize(rel.size() - 8);
    const size_t sep = rel.find(".overlapping/");
    if (sep == std::string::npos) continue;
    pairs.emplace_back(rel.substr(0, sep), rel.substr(sep + 13));
  }
  return pairs;
}

fs::path Kapture::MatchesPath(const std::string& keypoints_type, const std::string& image1,
                              const std::string& image2) const {
  ScanFeatures();
  const fs::path dir = MatchesDirOf(root_, cache_->legacy_keypoints_type, keypoints_type);
  return SafeJoin(dir, layout::MatchesFile(image1, image2),
                  std::string(layout::kMatches) + "/" + keypoints_type);
}

std::vector<Match> Kapture::ReadMatches(const std::string& keypoints_type,
                                        const std::string& image1,
                                        const std::string& image2) const {
  const bool swapped = image2 < image1;
  fs::path p = swapped ? MatchesPath(keypoints_type, image2, image1)
                       : MatchesPath(keypoints_type, image1, image2);
  bool reversed = swapped;
  if (!IsFile(p)) {
    // Not in the toolbox's order: accept the other one too.
    const fs::path q = swapped ? MatchesPath(keypoints_type, image1, image2)
                               : MatchesPath(keypoints_type, image2, image1);
    if (!IsFile(q))
      throw InputError(p.string(), 0, "", "missing matches file for (" + image1 + ", " + image2 + ")");
    p = q;
    reversed = !swapped;
  }
  std::vector<Match> m = MatchesFromArray(ReadFeatureFile(p, DType::kFloat64, 3, p.string()));
  if (reversed)
    for (Match& x : m) std::swap(x.index1, x.index2);
  return m;
}

const std::vector<Point3d>& Kapture::points3d() const {
  if (!cache_->points3d) {
    const fs::path p = root_ / layout::kPoints3d;
    cache_->points3d = IsFile(p) ? ReadPoints3d(p, layout::kPoints3d) : std::vector<Point3d>();
  }
  return *cache_->points3d;
}

const Observations& Kapture::observations() const {
  if (!cache_->observations) {
    ScanFeatures();
    const fs::path p = root_ / layout::kObservations;
    cache_->observations = IsFile(p) ? ReadObservations(p, layout::kObservations,
                                                        cache_->legacy_keypoints_type)
                                     : Observations();
  }
  return *cache_->observations;
}

// ---------------------------------------------------------------- writing

fs::path FeatureFilePath(const fs::path& root, FeatureKind kind, const std::string& type,
                         const std::string& image) {
  if (type.empty() || type.find('/') != std::string::npos || type == "." || type == "..")
    throw InputError(std::string(FeatureKindFolder(kind)) + " type '" + type +
                     "' is not a folder name");
  const fs::path dir = root / layout::FeatureRoot(kind) / type;
  return SafeJoin(dir, image + FeatureKindExtension(kind),
                  layout::FeatureRoot(kind) + "/" + type);
}

void WriteFeatureSetInfo(const fs::path& root, const std::string& type, const FeatureInfo& info) {
  FeatureFilePath(root, info.kind, type, "x");  // validates the type name
  WriteFeatureInfo(root / layout::FeatureRoot(info.kind) / type / InfoFileName(info.kind), info);
}

void WriteImageFeatures(const fs::path& root, const std::string& type, const FeatureInfo& info,
                        const std::string& image, const FeatureArray& array) {
  if (array.dtype != info.dtype || array.dsize != info.dsize)
    throw Error(std::string("features for ") + image + " are " + DTypeName(array.dtype) + " x " +
                std::to_string(array.dsize) + ", the type '" + type + "' holds " +
                DTypeName(info.dtype) + " x " + std::to_string(info.dsize));
  WriteFeatureFile(FeatureFilePath(root, info.kind, type, image), array);
}

LocalFeatureInfos MakeLocalFeatureInfos(const std::string& type, const std::string& name,
                                        int64_t keypoint_dims, DType descriptor_dtype,
                                        int64_t descriptor_dims, const std::string& metric,
                                        const std::string& descriptors_name) {
  LocalFeatureInfos infos;
  FeatureInfo& k = infos.keypoints;
  k.kind = FeatureKind::kKeypoints;
  k.name = name;
  k.dtype = DType::kFloat32;
  k.dtype_name = DTypeName(k.dtype);
  k.dsize = keypoint_dims;
  FeatureInfo& d = infos.descriptors;
  d.kind = FeatureKind::kDescriptors;
  d.name = descriptors_name.empty() ? name : descriptors_name;
  d.dtype = descriptor_dtype;
  d.dtype_name = DTypeName(descriptor_dtype);
  d.dsize = descriptor_dims;
  d.keypoints_type = type;
  d.metric_type = metric;
  return infos;
}

void WriteImageLocalFeatures(const fs::path& root, const std::string& type, const std::string& image,
                             const LocalFeatureInfos& infos, const FeatureArray& keypoints,
                             const FeatureArray& descriptors) {
  if (infos.keypoints.kind != FeatureKind::kKeypoints || infos.descriptors.kind != FeatureKind::kDescriptors)
    throw Error("WriteImageLocalFeatures: expected a keypoints info and a descriptors info");
  if (keypoints.rows != descriptors.rows)
    throw Error("features for " + image + ": " + std::to_string(keypoints.rows) + " keypoints but " +
                std::to_string(descriptors.rows) + " descriptors");
  WriteImageFeatures(root, type, infos.keypoints, image, keypoints);
  WriteImageFeatures(root, type, infos.descriptors, image, descriptors);
}

void WriteLocalFeatureSetInfos(const fs::path& root, const std::string& type,
                               const LocalFeatureInfos& infos) {
  WriteFeatureSetInfo(root, type, infos.keypoints);
  WriteFeatureSetInfo(root, type, infos.descriptors);
}

void WriteMatches(const fs::path& root, const std::string& keypoints_type,
                  const std::string& image1, const std::string& image2,
                  const std::vector<Match>& matches) {
  if (keypoints_type.empty() || keypoints_type.find('/') != std::string::npos)
    throw InputError("matches: keypoints type '" + keypoints_type + "' is not a folder name");
  const bool swap = image2 < image1;
  std::vector<Match> ordered = matches;
  if (swap)
    for (Match& m : ordered) std::swap(m.index1, m.index2);
  const fs::path dir = root / layout::kMatches / keypoints_type;
  const fs::path path = SafeJoin(dir, swap ? layout::MatchesFile(image2, image1)
                                           : layout::MatchesFile(image1, image2),
                                 std::string(layout::kMatches) + "/" + keypoints_type);
  WriteFeatureFile(path, MatchesToArray(ordered));
}

// ------------------------------------------------------------------- copy

bool CopyOptions::Check(std::string* why) const {
  (void)why;
  return true;
}

namespace {

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
  out.stream() << in.rdbuf();
  if (in.bad()) throw InputError(from.string(), 0, "", "read error");
  out.Commit();
}

void RewriteFeatureFile(const fs::path& from, const fs::path& to, DType dtype, int64_t dsize,
                        const std::string& display) {
  WriteFeatureFile(to, ReadFeatureFile(from, dtype, dsize, display));
}

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

bool IsDataRecordType(const std::string& type) {
  const RecordKind k = RecordKindOf(type);
  return k == RecordKind::kCamera || k == RecordKind::kLidar || k == RecordKind::kDepth;
}

constexpr size_t kListCap = 100;

}  // namespace

CopyReport CopyKapture(const fs::path& src, const fs::path& dst, const CopyOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw ParamError("copy options: " + why);
  Kapture k(src);
  CheckDestination(src, dst, options.overwrite);
  CopyReport report;
  const fs::path data_root = src / layout::kRecordsData;

  // Feature folders (1.1 per type or 1.0 single) by their path under src.
  std::vector<FeatureSet> sets;
  for (FeatureKind kind : kAllKinds)
    for (FeatureSet& s : k.FeatureSets(kind)) sets.push_back(std::move(s));
  const std::vector<std::string> match_types = k.MatchesTypes();
  k.observations();  // validates before anything is written
  k.points3d();

  int64_t missing = 0;
  // Walked, not listed: a dataset of 100k images must not be held in memory.
  for (auto it = fs::recursive_directory_iterator(src); it != fs::recursive_directory_iterator();
       ++it) {
    std::error_code type_ec;
    if (!it->is_regular_file(type_ec)) continue;
    const fs::path& file = it->path();
    const std::string rel = Rel(file, src);
    // A link may not lead out of the dataset.
    std::error_code ec;
    if (fs::is_symlink(file, ec)) SafeJoin(src, rel, rel);
    const fs::path out = dst / rel;
    const fs::path parent = file.parent_path();
    if (rel == layout::kSensors) {
      WriteSensors(out, k.sensors());
      ++report.text_files;
    } else if (rel == layout::kRigs) {
      WriteRigs(out, k.rigs());
      ++report.text_files;
    } else if (rel == layout::kTrajectories) {
      WriteTrajectories(out, k.trajectories());
      ++report.text_files;
    } else if (rel.rfind("sensors/records_", 0) == 0 && EndsWith(rel, ".txt") &&
               rel.find('/', 8) == std::string::npos) {
      const std::string type = rel.substr(16, rel.size() - 20);
      report.records += CopyRecordsFile(file, out, type, rel, data_root);
      ++report.text_files;
    } else if (rel.rfind(std::string(layout::kRecordsData) + "/", 0) == 0) {
      if (options.copy_records_data) {
        CopyVerbatim(file, out);
        ++report.data_files;
      }
    } else if (rel == layout::kPoints3d) {
      WritePoints3d(out, k.points3d());
      ++report.text_files;
    } else if (rel == layout::kObservations) {
      WriteObservations(out, k.observations());
      ++report.text_files;
    } else {
      // Feature files: the deepest feature folder holding this file.
      const FeatureSet* owner = nullptr;
      for (const FeatureSet& s : sets) {
        const std::string dir = Rel(s.dir, src) + "/";
        if (rel.rfind(dir, 0) == 0 &&
            (!owner || Rel(s.dir, src).size() > Rel(owner->dir, src).size()))
          owner = &s;
      }
      const std::string ext = owner ? FeatureKindExtension(owner->kind) : "";
      if (owner && parent == owner->dir && file.filename() == InfoFileName(owner->kind)) {
        WriteFeatureInfo(out, owner->info);
        ++report.text_files;
      } else if (owner && EndsWith(rel, ext)) {
        RewriteFeatureFile(file, out, owner->info.dtype, owner->info.dsize, rel);
        ++report.binary_files;
      } else if (rel.rfind(std::string(layout::kMatches) + "/", 0) == 0 &&
                 EndsWith(rel, ".matches")) {
        RewriteFeatureFile(file, out, DType::kFloat64, 3, rel);
        ++report.binary_files;
      } else {
        CopyVerbatim(file, out);
        ++report.other_files;
        report.notes.push_back("copied verbatim (not a kapture file): " + rel);
      }
    }
  }

  // Records naming files absent from the source: listed, not fatal.
  for (const std::string& type : k.RecordTypes()) {
    if (!IsDataRecordType(type)) continue;
    const std::string display = layout::RecordsFile(type);
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
  return report;
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

// ------------------------------------------------------------- inspection

namespace {

class ProblemList {
 public:
  explicit ProblemList(std::vector<std::string>* out) : out_(out) {}
  void Add(const std::string& category, const std::string& text) {
    if (++counts_[category] <= kPerCategory) out_->push_back(text);
  }
  void Close() {
    for (const auto& [category, n] : counts_)
      if (n > kPerCategory)
        out_->push_back("... " + std::to_string(n - kPerCategory) + " more " + category);
  }

 private:
  static constexpr int64_t kPerCategory = 10;
  std::vector<std::string>* out_;
  std::map<std::string, int64_t> counts_;
};

}  // namespace

KaptureSummary InspectKapture(const fs::path& root) {
  Kapture k(root);
  KaptureSummary s;
  s.root = root;
  ProblemList problems(&s.problems);

  const Sensors& sensors = k.sensors();
  for (const Sensor& sensor : sensors.list()) ++s.sensors_by_type[sensor.type];
  const Rigs& rigs = k.rigs();
  s.rigs = static_cast<int64_t>(rigs.size());
  s.rig_sensor_entries = static_cast<int64_t>(rigs.NumSensorEntries());
  for (const Rig& rig : rigs.list())
    for (const RigSensor& rs : rig.sensors)
      if (!sensors.Contains(rs.sensor_id))
        problems.Add("unknown rig sensors", std::string(layout::kRigs) + ": rig '" + rig.id +
                                                "' lists sensor '" + rs.sensor_id +
                                                "' absent from sensors.txt");

  const Trajectories& traj = k.trajectories();
  s.trajectory_poses = static_cast<int64_t>(traj.size());
  std::set<std::string> traj_devices;
  for (const auto& [key, pose] : traj.poses) {
    if (traj_devices.insert(key.second).second && !sensors.Contains(key.second) &&
        !rigs.Find(key.second))
      problems.Add("unknown trajectory devices",
                   std::string(layout::kTrajectories) + ": device '" + key.second +
                       "' is neither a sensor nor a rig");
  }
  s.trajectory_devices = static_cast<int64_t>(traj_devices.size());
  if (!traj.empty()) {
    s.trajectory_first = traj.poses.begin()->first.first;
    s.trajectory_last = traj.poses.rbegin()->first.first;
  }

  std::vector<FeatureSet> image_features;
  for (FeatureKind kind : kAllKinds)
    for (const FeatureSet& set : k.FeatureSets(kind)) {
      FeatureSummary f;
      f.kind = kind;
      f.type = set.type;
      f.info = set.info;
      f.files = static_cast<int64_t>(k.FeatureImages(kind, set.type).size());
      s.features.push_back(f);
      image_features.push_back(set);
    }

  const fs::path data_root = root / layout::kRecordsData;
  for (const std::string& type : k.RecordTypes()) {
    RecordsSummary rs;
    rs.sensor_type = type;
    std::set<std::string> devices;
    const std::string file = layout::RecordsFile(type);
    auto account = [&](Timestamp t, const std::string& device, int64_t line_hint) {
      (void)line_hint;
      if (rs.count == 0 || t < rs.first) rs.first = t;
      if (rs.count == 0 || t > rs.last) rs.last = t;
      ++rs.count;
      if (devices.insert(device).second && !sensors.Contains(device)) {
        problems.Add("unknown record devices",
                     file + ": device '" + device + "' is not in sensors.txt");
      }
      if (!sensors.Contains(device)) ++rs.unknown_devices;
    };
    const RecordKind kind = RecordKindOf(type);
    if (IsDataRecordType(type)) {
      auto reader = k.StreamRecords<DataRecord>(type);
      DataRecord r;
      while (reader.Next(&r)) {
        account(r.timestamp, r.device_id, 0);
        if (!IsFile(data_root / r.path)) {
          ++rs.missing_files;
          problems.Add("missing record files",
                       file + ": missing file " + std::string(layout::kRecordsData) + "/" + r.path);
        }
        if (kind == RecordKind::kCamera) {
          for (size_t i = 0; i < image_features.size(); ++i) {
            const FeatureSet& set = image_features[i];
            if (!IsFile(set.dir / (r.path + FeatureKindExtension(set.kind)))) {
              ++s.features[i].camera_records_without_file;
              problems.Add("missing feature files",
                           std::string(FeatureKindFolder(set.kind)) + "/" + set.type + ": no " +
                               FeatureKindExtension(set.kind) + " file for image " + r.path);
            }
          }
        }
      }
    } else {
      // Typed parsing validates every line; only the head is summarised.
      auto run = [&](auto reader, auto record) {
        while (reader.Next(&record)) account(record.timestamp, record.device_id, 0);
      };
      switch (kind) {
        case RecordKind::kGnss: run(k.StreamRecords<GnssRecord>(type), GnssRecord()); break;
        case RecordKind::kWifi: run(k.StreamRecords<WifiRecord>(type), WifiRecord()); break;
        case RecordKind::kBluetooth:
          run(k.StreamRecords<BluetoothRecord>(type), BluetoothRecord());
          break;
        case RecordKind::kAccelerometer:
        case RecordKind::kGyroscope:
        case RecordKind::kMagnetic:
          run(k.StreamRecords<Vector3Record>(type), Vector3Record());
          break;
        default: run(k.StreamRecords<GenericRecord>(type), GenericRecord()); break;
      }
    }
    rs.devices = static_cast<int64_t>(devices.size());
    s.records.push_back(rs);
  }

  for (const std::string& type : k.MatchesTypes())
    s.match_pairs[type] = static_cast<int64_t>(k.MatchPairs(type).size());
  s.points3d = static_cast<int64_t>(k.points3d().size());
  for (const ObservationsEntry& e : k.observations()) {
    ++s.observation_entries;
    s.observations += static_cast<int64_t>(e.features.size());
    if (e.point3d_id < 0 || e.point3d_id >= s.points3d)
      problems.Add("observations of unknown points",
                   std::string(layout::kObservations) + ": point3d_id " +
                       std::to_string(e.point3d_id) + " is not in points3d.txt");
  }
  problems.Close();
  return s;
}

std::string FormatSummary(const KaptureSummary& s) {
  std::string out = "kapture " + s.root.string() + "\n";
  auto line = [&](const std::string& text) { out += text + "\n"; };
  int64_t total_sensors = 0;
  std::string by_type;
  for (const auto& [type, n] : s.sensors_by_type) {
    total_sensors += n;
    by_type += (by_type.empty() ? "" : ", ") + type + " " + std::to_string(n);
  }
  line("sensors: " + std::to_string(total_sensors) + (by_type.empty() ? "" : " (" + by_type + ")"));
  line("rigs: " + std::to_string(s.rigs) + " (" + std::to_string(s.rig_sensor_entries) +
       " sensor entries)");
  line("trajectories: " + std::to_string(s.trajectory_poses) + " poses, " +
       std::to_string(s.trajectory_devices) + " devices" +
       (s.trajectory_poses ? ", timestamps " + std::to_string(s.trajectory_first) + " .. " +
                                 std::to_string(s.trajectory_last)
                           : ""));
  if (s.records.empty()) line("records: none");
  for (const RecordsSummary& r : s.records) {
    std::string text = "records " + r.sensor_type + ": " + std::to_string(r.count) + " from " +
                       std::to_string(r.devices) + " devices";
    if (r.count) text += ", timestamps " + std::to_string(r.first) + " .. " + std::to_string(r.last);
    if (r.missing_files) text += ", " + std::to_string(r.missing_files) + " files missing";
    if (r.unknown_devices) text += ", " + std::to_string(r.unknown_devices) + " of unknown devices";
    line(text);
  }
  if (s.features.empty()) line("features: none");
  for (const FeatureSummary& f : s.features) {
    std::string text = std::string(FeatureKindFolder(f.kind)) + " " + f.type + ": " + f.info.name +
                       ", " + f.info.dtype_name + " x " + std::to_string(f.info.dsize) + ", " +
                       std::to_string(f.files) + " files";
    if (!f.info.keypoints_type.empty()) text += ", keypoints " + f.info.keypoints_type;
    if (!f.info.metric_type.empty()) text += ", metric " + f.info.metric_type;
    if (f.camera_records_without_file)
      text += ", " + std::to_string(f.camera_records_without_file) + " camera records without one";
    line(text);
  }
  for (const auto& [type, n] : s.match_pairs)
    line("matches " + type + ": " + std::to_string(n) + " image pairs");
  line("reconstruction: " + std::to_string(s.points3d) + " points3d, " +
       std::to_string(s.observation_entries) + " observation lines (" +
       std::to_string(s.observations) + " observations)");
  if (s.problems.empty()) {
    line("problems: none");
  } else {
    line("problems: " + std::to_string(s.problems.size()) + " listed");
    for (const std::string& p : s.problems) line("  - " + p);
  }
  return out;
}

}  // namespace locforge::kapture

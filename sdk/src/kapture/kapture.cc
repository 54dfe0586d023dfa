// Reading a kapture dataset: Kapture, lazy and streamed (kapture.h).
#include "locforge/kapture/kapture.h"

#include <algorithm>
#include <mutex>
#include <set>

#include "locforge/error.h"
#include "locforge/kapture/rigs.h"
#include "files.h"

namespace locforge::kapture {

namespace layout {
std::string RecordsFile(const std::string& sensor_type) {
  return "sensors/records_" + sensor_type + ".txt";
}
std::string FeatureRoot(FeatureKind kind) {
  return std::string("reconstruction/") + FeatureKindFolder(kind);
}
std::string FeatureTarName(FeatureKind kind) {
  return std::string(FeatureKindFolder(kind)) + ".tar";
}
std::string MatchesFile(const std::string& image1, const std::string& image2) {
  return image1 + ".overlapping/" + image2 + ".matches";
}
}  // namespace layout

using namespace files;  // NOLINT: the library's own helpers

// Filled lazily on first use; `mutex` serialises the fills (and lookups of
// the feature maps), so threads may share one Kapture. A filled entry is
// never modified again, so the references handed out stay valid unlocked.
struct Kapture::Cache {
  std::recursive_mutex mutex;  // recursive: observations() scans the features
  std::optional<Sensors> sensors;
  std::optional<Rigs> rigs;
  std::optional<Trajectories> trajectories;
  std::optional<std::vector<Point3d>> points3d;
  std::optional<Observations> observations;
  bool features_scanned = false;
  std::map<std::pair<FeatureKind, std::string>, FeatureSet> features;
  std::map<std::pair<FeatureKind, std::string>, FeatureSet> attached;
  std::string legacy_keypoints_type;  // set when reconstruction/keypoints is 1.0 style
  std::map<std::string, std::shared_ptr<const TarArchive>> matches_archives;  // by type
};

Kapture::Kapture(fs::path root) : root_(std::move(root)), cache_(std::make_unique<Cache>()) {
  if (!IsDir(root_)) throw InputError(root_.string(), 0, "", "not a folder (expected a kapture root)");
}
Kapture::~Kapture() = default;
Kapture::Kapture(Kapture&&) noexcept = default;
Kapture& Kapture::operator=(Kapture&&) noexcept = default;

const Sensors& Kapture::sensors() const {
  std::lock_guard<std::recursive_mutex> lock(cache_->mutex);
  if (!cache_->sensors) {
    const fs::path p = root_ / layout::kSensors;
    cache_->sensors = IsFile(p) ? ReadSensors(p, layout::kSensors) : Sensors();
  }
  return *cache_->sensors;
}

const Rigs& Kapture::rigs() const {
  std::lock_guard<std::recursive_mutex> lock(cache_->mutex);
  if (!cache_->rigs) {
    const fs::path p = root_ / layout::kRigs;
    cache_->rigs = IsFile(p) ? ReadRigs(p, layout::kRigs) : Rigs();
  }
  return *cache_->rigs;
}

const Trajectories& Kapture::trajectories() const {
  std::lock_guard<std::recursive_mutex> lock(cache_->mutex);
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
  return JoinRecordPath(root_ / layout::kRecordsData, relative,
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
  std::lock_guard<std::recursive_mutex> lock(cache_->mutex);
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
  std::lock_guard<std::recursive_mutex> lock(cache_->mutex);
  ScanFeatures();
  std::vector<FeatureSet> out;
  for (const auto* m : {&cache_->features, &cache_->attached})
    for (const auto& [key, set] : *m)
      if (key.first == kind) out.push_back(set);
  return out;
}

const FeatureSet& Kapture::GetFeatureSet(FeatureKind kind, const std::string& type) const {
  std::lock_guard<std::recursive_mutex> lock(cache_->mutex);
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
  std::lock_guard<std::recursive_mutex> lock(cache_->mutex);
  ScanFeatures();
  return cache_->attached.count({kind, type}) || cache_->features.count({kind, type});
}

void Kapture::AttachFeatures(FeatureKind kind, const std::string& type, const fs::path& dir) {
  std::lock_guard<std::recursive_mutex> lock(cache_->mutex);
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
  return IsFile(FeatureFile(kind, type, image)) || ArchiveEntry(GetFeatureSet(kind, type), image);
}

FeatureArray Kapture::ReadFeatures(FeatureKind kind, const std::string& type,
                                   const std::string& image) const {
  const FeatureSet& set = GetFeatureSet(kind, type);
  const fs::path p = FeatureFile(kind, type, image);
  const TarEntry* entry = ArchiveEntry(set, image);
  if (IsFile(p) || !entry) return ReadFeatureFile(p, set.info.dtype, set.info.dsize, p.string());
  return FeatureArrayFromBytes(set.archive->Read(*entry), set.info.dtype, set.info.dsize,
                               EntryName(*set.archive, entry->name));
}

std::vector<std::string> Kapture::FeatureImages(FeatureKind kind, const std::string& type) const {
  const FeatureSet& set = GetFeatureSet(kind, type);
  const std::string ext = FeatureKindExtension(kind);
  std::set<std::string> images;
  for (const fs::path& f : FilesUnder(set.dir)) {
    const std::string rel = Rel(f, set.dir);
    if (EndsWith(rel, ext)) images.insert(rel.substr(0, rel.size() - ext.size()));
  }
  if (set.archive)
    for (const auto& [name, entry] : set.archive->entries())
      if (EndsWith(name, ext)) images.insert(name.substr(0, name.size() - ext.size()));
  return {images.begin(), images.end()};
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

namespace {
// "<image1>.overlapping/<image2>.matches" -> the pair; false for other names.
bool ParseMatchesName(std::string rel, std::pair<std::string, std::string>* pair) {
  if (!EndsWith(rel, ".matches")) return false;
  rel.resize(rel.size() - 8);
  const size_t sep = rel.find(".overlapping/");
  if (sep == std::string::npos) return false;
  *pair = {rel.substr(0, sep), rel.substr(sep + 13)};
  return true;
}
}  // namespace

const TarArchive* Kapture::MatchesArchive(const std::string& keypoints_type) const {
  std::lock_guard<std::recursive_mutex> lock(cache_->mutex);
  ScanFeatures();
  auto it = cache_->matches_archives.find(keypoints_type);
  if (it == cache_->matches_archives.end()) {
    const fs::path dir = MatchesDirOf(root_, cache_->legacy_keypoints_type, keypoints_type);
    const std::string display = Rel(dir, root_) + "/" + kMatchesTarName;
    std::shared_ptr<const TarArchive> archive;
    if (IsFile(dir / kMatchesTarName))
      archive = std::make_shared<const TarArchive>(dir / kMatchesTarName, display);
    it = cache_->matches_archives.emplace(keypoints_type, std::move(archive)).first;
  }
  return it->second.get();
}

std::vector<std::pair<std::string, std::string>> Kapture::MatchPairs(
    const std::string& keypoints_type) const {
  ScanFeatures();
  const fs::path dir = MatchesDirOf(root_, cache_->legacy_keypoints_type, keypoints_type);
  std::set<std::pair<std::string, std::string>> pairs;
  std::pair<std::string, std::string> pair;
  for (const fs::path& f : FilesUnder(dir))
    if (ParseMatchesName(Rel(f, dir), &pair)) pairs.insert(pair);
  if (const TarArchive* archive = MatchesArchive(keypoints_type))
    for (const auto& [name, entry] : archive->entries())
      if (ParseMatchesName(name, &pair)) pairs.insert(pair);
  return {pairs.begin(), pairs.end()};
}

fs::path Kapture::MatchesPath(const std::string& keypoints_type, const std::string& image1,
                              const std::string& image2) const {
  ScanFeatures();
  const fs::path dir = MatchesDirOf(root_, cache_->legacy_keypoints_type, keypoints_type);
  return SafeJoin(dir, layout::MatchesFile(image1, image2),
                  std::string(layout::kMatches) + "/" + keypoints_type);
}

namespace {
// The matches stored as (a, b): the loose file, else the archive's entry.
std::optional<FeatureArray> StoredMatches(const fs::path& file, const TarArchive* archive,
                                          const std::string& a, const std::string& b) {
  if (IsFile(file)) return ReadFeatureFile(file, DType::kFloat64, 3, file.string());
  const std::string name = layout::MatchesFile(a, b);
  const TarEntry* entry = archive ? archive->Find(name) : nullptr;
  if (!entry) return std::nullopt;
  return FeatureArrayFromBytes(archive->Read(*entry), DType::kFloat64, 3,
                               EntryName(*archive, name));
}
}  // namespace

std::vector<Match> Kapture::ReadMatches(const std::string& keypoints_type,
                                        const std::string& image1,
                                        const std::string& image2) const {
  // The toolbox's order (smaller name first), else the other one too.
  const bool swapped = image2 < image1;
  const std::string& a = swapped ? image2 : image1;
  const std::string& b = swapped ? image1 : image2;
  const TarArchive* archive = MatchesArchive(keypoints_type);
  bool reversed = swapped;
  std::optional<FeatureArray> array = StoredMatches(MatchesPath(keypoints_type, a, b), archive, a, b);
  if (!array) {
    array = StoredMatches(MatchesPath(keypoints_type, b, a), archive, b, a);
    reversed = !swapped;
  }
  if (!array)
    throw InputError(MatchesPath(keypoints_type, a, b).string(), 0, "",
                     "missing matches file for (" + image1 + ", " + image2 + ")");
  std::vector<Match> m = MatchesFromArray(*array);
  if (reversed)
    for (Match& x : m) std::swap(x.index1, x.index2);
  return m;
}

const std::vector<Point3d>& Kapture::points3d() const {
  std::lock_guard<std::recursive_mutex> lock(cache_->mutex);
  if (!cache_->points3d) {
    const fs::path p = root_ / layout::kPoints3d;
    cache_->points3d = IsFile(p) ? ReadPoints3d(p, layout::kPoints3d) : std::vector<Point3d>();
  }
  return *cache_->points3d;
}

const Observations& Kapture::observations() const {
  std::lock_guard<std::recursive_mutex> lock(cache_->mutex);
  if (!cache_->observations) {
    ScanFeatures();
    const fs::path p = root_ / layout::kObservations;
    cache_->observations = IsFile(p) ? ReadObservations(p, layout::kObservations,
                                                        cache_->legacy_keypoints_type)
                                     : Observations();
  }
  return *cache_->observations;
}

}  // namespace locforge::kapture

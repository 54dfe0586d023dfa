// A kapture 1.1 dataset folder with lazy access, plus copy and inspection.
//
// Layout (kapture 1.1):
//   sensors/sensors.txt, rigs.txt, trajectories.txt, records_<type>.txt
//   sensors/records_data/<path of each camera/lidar/depth record>
//   reconstruction/keypoints/<type>/keypoints.txt + <image>.kpt
//   reconstruction/descriptors/<type>/descriptors.txt + <image>.desc
//   reconstruction/global_features/<type>/global_features.txt + <image>.gfeat
//   reconstruction/matches/<keypoints type>/<image1>.overlapping/<image2>.matches
//   reconstruction/points3d.txt, reconstruction/observations.txt
// A type folder may keep its per-image files packed in one archive instead
// (kapture 1.1 tar-packed features, tar.h): <kind>/<type>/<kind>.tar
// holding "<image><ext>", matches/<type>/matches.tar holding
// "<image1>.overlapping/<image2>.matches". They are read in place; a file
// present both loose and in the archive reads from the loose file.
// The kapture 1.0 single-type layout (reconstruction/keypoints/keypoints.txt
// + <image>.kpt, matches/<image1>.overlapping/...) is read too, with the
// type named by the .txt's `name`, and kept as it was by CopyKapture.
//
// Nothing is read at construction. Sensors, rigs and trajectories are parsed
// on first access and cached; records are streamed from their file on each
// call; feature files are read per image on demand. The const readers may be
// called from several threads on one Kapture: the lazy caches are filled
// under a lock. AttachFeatures is setup: call it before sharing the object.
#ifndef LOCFORGE_KAPTURE_KAPTURE_H_
#define LOCFORGE_KAPTURE_KAPTURE_H_

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "locforge/fs.h"
#include "locforge/kapture/features.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/tar.h"
#include "locforge/kapture/types.h"

namespace locforge::kapture {

// Paths of the layout, relative to a kapture root.
namespace layout {
inline constexpr const char* kSensors = "sensors/sensors.txt";
inline constexpr const char* kRigs = "sensors/rigs.txt";
inline constexpr const char* kTrajectories = "sensors/trajectories.txt";
inline constexpr const char* kRecordsData = "sensors/records_data";
inline constexpr const char* kReconstruction = "reconstruction";
inline constexpr const char* kPoints3d = "reconstruction/points3d.txt";
inline constexpr const char* kObservations = "reconstruction/observations.txt";
inline constexpr const char* kMatches = "reconstruction/matches";
// "sensors/records_camera.txt" for "camera".
std::string RecordsFile(const std::string& sensor_type);
// "reconstruction/keypoints" etc.
std::string FeatureRoot(FeatureKind kind);
// "keypoints.tar", "descriptors.tar", "global_features.tar": a type
// folder's archive.
std::string FeatureTarName(FeatureKind kind);
// "<image1>.overlapping/<image2>.matches" (no ordering applied).
std::string MatchesFile(const std::string& image1, const std::string& image2);
}  // namespace layout

// A type of feature of the dataset: where its files are and their format.
struct FeatureSet {
  FeatureKind kind = FeatureKind::kKeypoints;
  std::string type;    // folder name (1.1) or the .txt's name (1.0 layout)
  fs::path dir;        // holds <kind>.txt and the per-image files
  FeatureInfo info;
  bool legacy_layout = false;  // 1.0: dir is reconstruction/<kind> itself
  // dir/<kind>.tar when the type is tar-packed (indexed once), else null.
  std::shared_ptr<const TarArchive> archive;
};

class Kapture {
 public:
  // Throws InputError when `root` is not an existing folder.
  explicit Kapture(fs::path root);
  ~Kapture();
  Kapture(Kapture&&) noexcept;
  Kapture& operator=(Kapture&&) noexcept;

  const fs::path& root() const { return root_; }

  // --- sensors/ (each empty when its file is absent), parsed once.
  const Sensors& sensors() const;
  const Rigs& rigs() const;
  const Trajectories& trajectories() const;
  // Own trajectory entry, else composed from the rig's (rigs.h).
  std::optional<Pose> DevicePose(Timestamp timestamp, const std::string& device_id) const;

  // --- records: types with a records_<type>.txt, sorted ("bluetooth",
  // "camera", "lidar", ...).
  std::vector<std::string> RecordTypes() const;
  bool HasRecords(const std::string& sensor_type) const;
  // Streams records_<type>.txt (O(one record) memory). DataRecord paths are
  // checked against records_data (no absolute path, no ".." out of it;
  // symbolic links the owner placed under it are followed).
  template <class Record>
  RecordsReader<Record> StreamRecords(const std::string& sensor_type) const {
    return RecordsReader<Record>(root_ / layout::RecordsFile(sensor_type),
                                 layout::RecordsFile(sensor_type), root_ / layout::kRecordsData);
  }
  // Whole records_camera.txt / records_lidar.txt / records_depth.txt.
  std::vector<DataRecord> ReadDataRecords(const std::string& sensor_type) const;
  // Calls fn for each record of a camera/lidar/depth file, streaming.
  void ForEachDataRecord(const std::string& sensor_type,
                         const std::function<void(const DataRecord&)>& fn) const;
  // Image names of records_camera.txt, sorted, each once (the item list of
  // per-image stages).
  std::vector<std::string> CameraImages() const;
  // Absolute path of a record's file under sensors/records_data, refusing
  // lexical escapes: absolute, ".." (InputError naming `origin`, e.g.
  // "sensors/records_camera.txt:3"). Links under it are followed.
  fs::path RecordDataPath(const std::string& relative, const std::string& origin = "") const;
  // Same, and throws InputError "... missing file" when it does not exist.
  fs::path ExistingRecordDataPath(const std::string& relative,
                                  const std::string& origin = "") const;

  // --- features. Types found under reconstruction/ plus attached ones.
  std::vector<FeatureSet> FeatureSets(FeatureKind kind) const;
  // Throws InputError when the type is absent.
  const FeatureSet& GetFeatureSet(FeatureKind kind, const std::string& type) const;
  bool HasFeatureType(FeatureKind kind, const std::string& type) const;
  // Adds a feature folder living outside the kapture (kapture-localization
  // keeps e.g. local_features/r2d2_500/keypoints/ with keypoints.txt and
  // <image>.kpt files); it then reads like a built-in type. Not to be called
  // while other threads read the same type.
  void AttachFeatures(FeatureKind kind, const std::string& type, const fs::path& dir);

  // <dir>/<image><ext>, refusing escapes. For a tar-packed type this loose
  // path need not exist: use HasFeatureFile / ReadFeatures.
  fs::path FeatureFile(FeatureKind kind, const std::string& type, const std::string& image) const;
  bool HasFeatureFile(FeatureKind kind, const std::string& type, const std::string& image) const;
  // Reads one image's file with the dtype/dsize of the type; InputError on a
  // missing or malformed file (message names it).
  FeatureArray ReadFeatures(FeatureKind kind, const std::string& type,
                            const std::string& image) const;
  FeatureArray ReadKeypoints(const std::string& type, const std::string& image) const {
    return ReadFeatures(FeatureKind::kKeypoints, type, image);
  }
  FeatureArray ReadDescriptors(const std::string& type, const std::string& image) const {
    return ReadFeatures(FeatureKind::kDescriptors, type, image);
  }
  FeatureArray ReadGlobalFeatures(const std::string& type, const std::string& image) const {
    return ReadFeatures(FeatureKind::kGlobalFeatures, type, image);
  }
  // Images with a file of this type (walks the folder, lists the archive),
  // sorted.
  std::vector<std::string> FeatureImages(FeatureKind kind, const std::string& type) const;

  // --- matches
  std::vector<std::string> MatchesTypes() const;
  // (image1, image2) pairs with a .matches file (loose or in the type's
  // matches.tar), image1 < image2, sorted.
  std::vector<std::pair<std::string, std::string>> MatchPairs(const std::string& keypoints_type) const;
  // The loose file's path (for a tar-packed type it need not exist).
  fs::path MatchesPath(const std::string& keypoints_type, const std::string& image1,
                       const std::string& image2) const;
  // Either image order: when (image1, image2) is stored as (image2, image1)
  // the index columns are swapped so index1 always refers to image1.
  // Throws InputError when no file exists for the pair.
  std::vector<Match> ReadMatches(const std::string& keypoints_type, const std::string& image1,
                                 const std::string& image2) const;

  // --- reconstruction/ (empty when absent), parsed once.
  const std::vector<Point3d>& points3d() const;
  const Observations& observations() const;

 private:
  struct Cache;
  void ScanFeatures() const;
  // matches/<type>/matches.tar, indexed on first use; null when absent.
  const TarArchive* MatchesArchive(const std::string& keypoints_type) const;
  fs::path root_;
  std::unique_ptr<Cache> cache_;
};

// --------------------------------------------------------------- writing
// Per-file writers are in io.h and features.h; these place files in the 1.1
// layout under a kapture root.

// <root>/reconstruction/<kind>/<type>/<image><ext>, refusing escapes.
fs::path FeatureFilePath(const fs::path& root, FeatureKind kind, const std::string& type,
                         const std::string& image);
// Writes <kind>.txt of a type: <root>/reconstruction/<kind>/<type>/<kind>.txt.
void WriteFeatureSetInfo(const fs::path& root, const std::string& type, const FeatureInfo& info);
// Writes one image's feature file (atomically), checking the array's dtype
// and dsize against `info`.
void WriteImageFeatures(const fs::path& root, const std::string& type, const FeatureInfo& info,
                        const std::string& image, const FeatureArray& array);
// The keypoints.txt and descriptors.txt infos of one local feature type as a
// feature extractor writes them (features/sift, features/r2d2, features/d2net):
// keypoints float32 x keypoint_dims named `name`; descriptors of
// descriptor_dtype x descriptor_dims named `descriptors_name` (empty: `name`),
// keypoints_type `type`, metric `metric`.
struct LocalFeatureInfos {
  FeatureInfo keypoints;
  FeatureInfo descriptors;
};
LocalFeatureInfos MakeLocalFeatureInfos(const std::string& type, const std::string& name,
                                        int64_t keypoint_dims, DType descriptor_dtype,
                                        int64_t descriptor_dims, const std::string& metric = "L2",
                                        const std::string& descriptors_name = "");
// Writes one image's local features: keypoints then descriptors, each file
// atomically, after checking both arrays against their infos and that they
// have the same number of rows (the per-image output of feature extractors).
void WriteImageLocalFeatures(const fs::path& root, const std::string& type, const std::string& image,
                             const LocalFeatureInfos& infos, const FeatureArray& keypoints,
                             const FeatureArray& descriptors);
// Writes both <kind>.txt files of the type (WriteFeatureSetInfo twice).
void WriteLocalFeatureSetInfos(const fs::path& root, const std::string& type,
                               const LocalFeatureInfos& infos);
// Writes the matches of a pair in the toolbox's order: stored under the
// smaller image name, index columns swapped when image2 < image1.
void WriteMatches(const fs::path& root, const std::string& keypoints_type,
                  const std::string& image1, const std::string& image2,
                  const std::vector<Match>& matches);

// ------------------------------------------------------------------- copy

struct CopyOptions {
  // Copy sensors/records_data files (images, depth maps, point clouds).
  bool copy_records_data = true;
  // Allow a destination folder that exists and is not empty.
  bool overwrite = false;
  // Write the files of tar-packed feature and matches types loose (checked
  // like loose ones) instead of copying their archives.
  bool unpack_archives = false;

  bool Check(std::string* why) const;
};

struct CopyReport {
  int64_t text_files = 0;      // re-emitted kapture text files
  int64_t binary_files = 0;    // feature / matches files re-written
  int64_t data_files = 0;      // records_data files copied
  int64_t other_files = 0;     // unrecognised files copied verbatim
  int64_t records = 0;         // record lines re-emitted
  std::vector<std::string> missing_data_files;  // referenced, absent in SRC
  std::vector<std::string> notes;               // e.g. unrecognised files copied
};

// Reads everything under `src` and writes it to `dst`: text files parsed and
// re-emitted in the toolbox's format, records streamed, feature and matches
// files validated (size vs dtype/dsize) and re-written byte for byte,
// feature and matches archives (tar-packed types) kept packed: every entry
// validated the same way, the archive copied byte for byte (counted as one
// binary file), or with options.unpack_archives written loose,
// records_data files copied, unrecognised files copied verbatim (listed in
// notes). Refuses (InputError) a destination equal to, inside or containing
// the source, a non-empty destination unless options.overwrite, and any
// records path escaping the source. Missing record data files are listed,
// not fatal (public samples ship without their images).
CopyReport CopyKapture(const fs::path& src, const fs::path& dst,
                       const CopyOptions& options = {});

// Copies a stand-alone feature folder (a <kind>.txt with its per-image
// files, as kapture-localization keeps them): .txt re-emitted, files
// validated and re-written. Returns the number of feature files.
int64_t CopyFeatureFolder(FeatureKind kind, const fs::path& src, const fs::path& dst,
                          bool overwrite = false);

// ----------------------------------------------------------------- export

// One kapture folder to export from, whole or partial (a workspace node's
// folder holds only what its stage made: features alone, matches alone, ...).
struct ExportSource {
  std::string name;  // what messages call it, e.g. the node's name
  fs::path dir;
};

struct ExportOptions {
  // Records' files as symbolic links to the source's files (their canonical
  // path); false: copied.
  bool link_records_data = true;
  // Replace a destination folder that exists and is not empty.
  bool overwrite = false;
  // The source whose sensors/trajectories.txt is exported (the others' are
  // left out); empty: every source's, merged.
  std::string trajectories_from;
};

struct ExportReport {
  int64_t sensors = 0, rigs = 0, trajectory_poses = 0;
  std::map<std::string, int64_t> records;        // by sensor type
  int64_t data_files = 0;                        // records_data files linked or copied
  std::map<std::string, int64_t> feature_files;  // by "<kind>/<type>"
  std::map<std::string, int64_t> match_pairs;    // by keypoints type
  int64_t points3d = 0, observation_entries = 0;
  int64_t missing_data_count = 0;                // records whose file is absent in their source
  std::vector<std::string> missing_data_files;   // the first 100 of them
};

// Writes one complete kapture 1.1 at `dst` from several partial ones, as
// the toolbox lays it out (so kapture-localization takes it): sensors, rigs
// and trajectories merged by id / (timestamp, device); every other file
// (records_<type>.txt, <kind>.txt, feature, matches, points3d and
// observations files) re-emitted from the first source holding it, and a
// later source holding it too must hold the same (re-emitted) bytes; tar-
// packed types are written loose. Records' files under records_data are
// linked or copied (options). Refuses (InputError, naming the file, the
// field or line and both sources) two sources that disagree, a source
// holding no kapture file, and a destination as CopyKapture does. Built in a
// temporary sibling folder renamed to `dst` once complete: `dst` is never
// left half written.
ExportReport ExportKapture(const std::vector<ExportSource>& sources, const fs::path& dst,
                           const ExportOptions& options = {});

// ------------------------------------------------------------- inspection

struct RecordsSummary {
  std::string sensor_type;
  int64_t count = 0;
  int64_t devices = 0;
  Timestamp first = 0, last = 0;
  int64_t missing_files = 0;     // DataRecord files absent under records_data
  int64_t unknown_devices = 0;   // records whose device is not in sensors.txt
};

struct FeatureSummary {
  FeatureKind kind = FeatureKind::kKeypoints;
  std::string type;
  FeatureInfo info;
  int64_t files = 0;
  int64_t camera_records_without_file = 0;  // images of records_camera lacking one
};

struct KaptureSummary {
  fs::path root;
  std::map<std::string, int64_t> sensors_by_type;
  int64_t rigs = 0, rig_sensor_entries = 0;
  int64_t trajectory_poses = 0, trajectory_devices = 0;
  Timestamp trajectory_first = 0, trajectory_last = 0;
  std::vector<RecordsSummary> records;
  std::vector<FeatureSummary> features;
  std::map<std::string, int64_t> match_pairs;  // by keypoints type
  int64_t points3d = 0, observation_entries = 0, observations = 0;
  // Human-readable problems (capped per kind; counts are in the fields).
  std::vector<std::string> problems;
};

// Reads every file (records streamed) and checks cross references: record
// files present, record devices known, trajectory devices known (sensor or
// rig), rig sensors known, feature files present for camera records. Throws
// InputError on malformed files; soft problems go to `problems`.
KaptureSummary InspectKapture(const fs::path& root);
std::string FormatSummary(const KaptureSummary& summary);

// The camera records whose image file exists but does not decode whole
// (locforge/image_check.h), in record order; missing files are Inspect's.
struct DamagedImage {
  std::string path;    // as in records_camera.txt
  std::string reason;  // e.g. "truncated JPEG (libjpeg: Premature end of JPEG file)"
};
// `checked` (optional) receives the number of image files checked.
std::vector<DamagedImage> FindDamagedImages(const Kapture& kapture, int64_t* checked = nullptr);

}  // namespace locforge::kapture

#endif  // LOCFORGE_KAPTURE_KAPTURE_H_

// Readers and writers of every kapture 1.1 text file, one per file so a
// caller can read, stream or write any of them alone.
//
// Readers throw InputError naming file, line and field; they never drop a
// line silently. Writers emit the toolbox's layout: "# kapture format: 1.1",
// the column comment, fields joined by ", ", floats as Python's repr
// (points3d.txt as numpy.savetxt "%.18e"), "\n" line ends; every file is
// written atomically (fs.h).
//
// `display_name` arguments are what error messages call the file (e.g.
// "sensors/sensors.txt"); empty means the path as given.
#ifndef LOCFORGE_KAPTURE_IO_H_
#define LOCFORGE_KAPTURE_IO_H_

#include <istream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "locforge/fs.h"
#include "locforge/kapture/csv.h"
#include "locforge/kapture/features.h"
#include "locforge/kapture/types.h"

namespace locforge::kapture {

// ----------------------------------------------------- sensors, rigs, poses

Sensors ReadSensors(const fs::path& path, const std::string& display_name = "");
Sensors ParseSensors(std::istream& in, const std::string& display_name);
void WriteSensors(const fs::path& path, const Sensors& sensors);

Rigs ReadRigs(const fs::path& path, const std::string& display_name = "");
Rigs ParseRigs(std::istream& in, const std::string& display_name);
void WriteRigs(const fs::path& path, const Rigs& rigs);

// kapture 1.1 trajectories: "timestamp, device_id, qw, qx, qy, qz, tx, ty,
// tz" (no covariance column); one pose per (timestamp, device), a second one
// is refused.
Trajectories ReadTrajectories(const fs::path& path, const std::string& display_name = "");
Trajectories ParseTrajectories(std::istream& in, const std::string& display_name);
// Sorted by (timestamp, device); timestamps right-aligned to 8 characters,
// device ids to 3 and empty pose fields to 4, as the toolbox's files are
// padded (csv.py PADDINGS; WriteRigs pads rig and sensor ids to 3).
void WriteTrajectories(const fs::path& path, const Trajectories& trajectories);

// Parses "qw, qx, qy, qz, tx, ty, tz" fields starting at row.fields[first]
// into a pose with a unit quaternion. Four empty rotation fields make a
// translation-only pose, three empty translation fields a rotation-only one,
// all seven empty the identity with neither part (PoseParts::kNone, as the
// toolbox reads it) (`parts`). `raw_rotation` (optional) receives the file's quaternion when
// normalising changed it.
Pose ParsePoseFields(const CsvRow& row, size_t first, const std::string& file, PoseParts* parts,
                     std::optional<Eigen::Vector4d>* raw_rotation = nullptr);
// Seven fields, empty for a missing part. `raw_rotation`, when given and
// still normalising to pose.q exactly, is written instead of pose.q.
std::vector<std::string> FormatPoseFields(const Pose& pose, PoseParts parts,
                                          const Eigen::Vector4d* raw_rotation = nullptr);

// ------------------------------------------------------------------ records

// Streams records_<type>.txt one record at a time (memory O(one record)).
// Record is one of DataRecord, GnssRecord, WifiRecord, BluetoothRecord,
// Vector3Record, GenericRecord. Wifi is read in the 1.1 column order only
// (the 1.0 order "BSSID, RSSI, frequency, ..." is refused by its count).
// Records are kept in file order; nothing is sorted or deduplicated.
//
// DataRecord paths are checked: an absolute path or one that climbs out of
// records_data ("..") is refused with InputError naming file and line.
// Symbolic links under records_data are followed: links the dataset's owner
// placed there (kapture's link_absolute / link_relative imports) are the
// owner's choice (JoinRecordPath). The file's existence is NOT required here
// (see Kapture::RecordDataPath and the inspection report).
template <class Record>
class RecordsReader {
 public:
  explicit RecordsReader(const fs::path& path, const std::string& display_name = "",
                         fs::path records_data_root = {});
  RecordsReader(std::istream& in, const std::string& display_name,
                fs::path records_data_root = {});
  RecordsReader(RecordsReader&&) noexcept;
  RecordsReader& operator=(RecordsReader&&) noexcept;
  ~RecordsReader();

  bool Next(Record* record);
  const std::string& name() const;
  // The source's column comment (e.g. "timestamp, device_id, pcd_path"), or
  // "" if none: GenericRecord writers reuse it.
  std::string ColumnsComment() const;

  struct PathCheck;  // checked folders, so a path costs ~one stat, not one per component

 private:
  std::unique_ptr<CsvReader> csv_;
  std::unique_ptr<PathCheck> paths_;
};

// Writes records_<type>.txt incrementally; the file appears on Commit()
// (atomic); destroyed without Commit(), nothing is written.
template <class Record>
class RecordsWriter {
 public:
  // `columns` overrides the column comment (without "# "); empty -> the
  // toolbox's for this kind (GenericRecord: "timestamp, device_id, data").
  RecordsWriter(const fs::path& path, RecordKind kind, const std::string& columns = "");
  ~RecordsWriter();
  void Write(const Record& record);
  void Commit();
  int64_t count() const { return count_; }

 private:
  std::unique_ptr<AtomicFile> file_;
  int64_t count_ = 0;
};

// Whole-file helpers on top of the streaming ones.
template <class Record>
std::vector<Record> ReadRecords(const fs::path& path, const std::string& display_name = "",
                                const fs::path& records_data_root = {});
template <class Record>
void WriteRecords(const fs::path& path, RecordKind kind, const std::vector<Record>& records,
                  const std::string& columns = "");

// One record line to fields and back (used by the readers/writers above and
// by the fuzz target).
DataRecord ParseDataRecord(const CsvRow& row, const std::string& file);
GnssRecord ParseGnssRecord(const CsvRow& row, const std::string& file);
WifiRecord ParseWifiRecord(const CsvRow& row, const std::string& file);
BluetoothRecord ParseBluetoothRecord(const CsvRow& row, const std::string& file);
Vector3Record ParseVector3Record(const CsvRow& row, const std::string& file);
GenericRecord ParseGenericRecord(const CsvRow& row, const std::string& file);

// ------------------------------------------------- features configuration

// keypoints.txt, descriptors.txt, global_features.txt: one data line.
FeatureInfo ReadFeatureInfo(const fs::path& path, FeatureKind kind,
                            const std::string& display_name = "");
FeatureInfo ParseFeatureInfo(std::istream& in, FeatureKind kind, const std::string& display_name);
void WriteFeatureInfo(const fs::path& path, const FeatureInfo& info);

// ----------------------------------------------------------- reconstruction

// "X, Y, Z, R, G, B" or "X, Y, Z" (points without colours: has_color false),
// as the column comment says, else as the first line has; every line alike.
// Written with the colour columns unless no point has a colour.
std::vector<Point3d> ReadPoints3d(const fs::path& path, const std::string& display_name = "");
std::vector<Point3d> ParsePoints3d(std::istream& in, const std::string& display_name);
void WritePoints3d(const fs::path& path, const std::vector<Point3d>& points);

// Reads the 1.1 form "point3d_id, keypoints_type, [image_path, feature_id]*"
// and the 1.0 form "point3d_id, [image_path, feature_id]*" (told apart by
// the version header, else by the field count's parity). 1.0 entries get
// `default_keypoints_type`.
Observations ReadObservations(const fs::path& path, const std::string& display_name = "",
                              const std::string& default_keypoints_type = "");
Observations ParseObservations(std::istream& in, const std::string& display_name,
                               const std::string& default_keypoints_type = "");
// Always the 1.1 form; throws Error for an entry with an empty keypoints type.
void WriteObservations(const fs::path& path, const Observations& observations);

}  // namespace locforge::kapture

#endif  // LOCFORGE_KAPTURE_IO_H_

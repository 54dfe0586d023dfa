// Helpers shared by the stages of the SfM half of the ground truth
// (calib/perturb, gt/images, gt/spline_ba, eval/calibration): file linking,
// camera groups, sequence splitting, small tables.
#ifndef LOCFORGE_PLUGINS_COMMON_SFM_GT_SFM_GT_COMMON_H_
#define LOCFORGE_PLUGINS_COMMON_SFM_GT_SFM_GT_COMMON_H_

#include <map>
#include <string>
#include <vector>

#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/pose.h"

namespace locforge::sfm_gt {

namespace kp = locforge::kapture;

// Hard-links every regular file under `src` into the same place under `dst`
// (copies when a link is impossible, e.g. across file systems); each file is
// first made under a temporary name and renamed, so an interrupted run never
// leaves a partial file. Returns the number of files.
int64_t LinkTree(const fs::path& src, const fs::path& dst);

// Links (or copies) the data files of `records` from `from` (a kapture
// root) into `to`; paths are resolved with Kapture::ExistingRecordDataPath,
// so none leaves the source root.
int64_t LinkRecordData(const kp::Kapture& from, const std::vector<kp::DataRecord>& records,
                       const fs::path& to);

// "NAME=REGEX" entries, e.g. {"industrial=ind_.*", "smartphone=phone_.*"}.
struct CameraGroups {
  std::vector<std::pair<std::string, std::string>> groups;  // name, regex
  // Throws ParamError naming the entry when one is malformed.
  static CameraGroups Parse(const std::vector<std::string>& entries);
  // First group whose regex matches the whole sensor id, "other" otherwise.
  std::string Of(const std::string& sensor_id) const;
};

// Rig poses of one platform trajectory (one sequence), sorted by time.
struct RigSequence {
  std::vector<Timestamp> timestamps;
  std::vector<Pose> T_world_rig;
};
// Splits the poses of `rig_id` in `trajectories` into sequences wherever two
// consecutive timestamps are more than `max_gap` apart (dataset units).
std::vector<RigSequence> SplitRigSequences(const kp::Trajectories& trajectories,
                                           const std::string& rig_id, Timestamp max_gap);
// Index of the sequence whose time span (extended by `margin`) holds t, or -1.
int SequenceOf(const std::vector<RigSequence>& sequences, Timestamp t, Timestamp margin);

// A small table written as Markdown and CSV.
struct TextTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::string Markdown() const;
  std::string Csv() const;
};
std::string Fixed(double value, int decimals);

}  // namespace locforge::sfm_gt

#endif  // LOCFORGE_PLUGINS_COMMON_SFM_GT_SFM_GT_COMMON_H_

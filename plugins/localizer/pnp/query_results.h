// Per-query results of the localizer stages (localizer/pnp, localizer/posenet,
// localizer/esac): each query item writes one small file atomically when it is
// processed (so the stage shards and resumes), and Finalize turns them into
// the kapture trajectories, failures.txt and localization_stats.csv. A failed
// query is listed with its reason and never given a pose.
#ifndef LOCFORGE_PLUGINS_LOCALIZER_PNP_QUERY_RESULTS_H_
#define LOCFORGE_PLUGINS_LOCALIZER_PNP_QUERY_RESULTS_H_

#include <string>
#include <vector>

#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/pose.h"

namespace locforge::localization {

struct QueryOutcome {
  bool success = false;
  Pose device_from_world;     // the estimate (T_device_world), when success
  std::string failure;        // why not, when !success (one line)
  std::vector<double> stats;  // the stage's stat columns, in its header's order
};

// The file of one item under `output_dir`/results (item names are image
// paths or rig ids, kept inside the folder by SafeJoin).
fs::path QueryResultFile(const fs::path& output_dir, const std::string& item);

// Writes `outcome` atomically to QueryResultFile(output_dir, item).
void WriteQueryResult(const fs::path& output_dir, const std::string& item,
                      const QueryOutcome& outcome);

// Reads back what WriteQueryResult wrote; InputError naming the file when
// it is malformed or has another number of stats than `stat_count`.
QueryOutcome ReadQueryResult(const fs::path& output_dir, const std::string& item,
                             size_t stat_count);

struct QueryItemInfo {
  std::string name;    // the item (its results file)
  Timestamp timestamp = 0;
  std::string device;  // trajectory device: the camera, or the rig
};

// Writes sensors (+ rigs), trajectories.txt, failures.txt and
// localization_stats.csv (columns item,status,<stat_names...>) under
// `output_dir` from the items' result files. Returns the number localized.
int WriteLocalizationOutputs(const fs::path& output_dir, const std::vector<QueryItemInfo>& items,
                             const std::vector<std::string>& stat_names,
                             const kapture::Sensors& sensors, const kapture::Rigs& rigs);

}  // namespace locforge::localization

#endif  // LOCFORGE_PLUGINS_LOCALIZER_PNP_QUERY_RESULTS_H_

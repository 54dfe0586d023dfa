// Several kapture folders merged into one camera dataset: the simulator's
// validation/ and test/ query kaptures become one query set whose image paths
// keep their split ("validation/val_00/ind_0/...jpg"), so one localization run
// and one evaluation (splits by image path) cover both.
#ifndef LOCFORGE_PLUGINS_SOURCE_KAPTURE_FOLDER_KAPTURE_MERGE_H_
#define LOCFORGE_PLUGINS_SOURCE_KAPTURE_FOLDER_KAPTURE_MERGE_H_

#include <string>
#include <vector>

#include "locforge/fs.h"

namespace locforge::colmap_stages {

struct MergeSource {
  fs::path root;       // a kapture root
  std::string prefix;  // prepended to its image paths ("" keeps them)
};

struct MergeReport {
  int64_t sensors = 0;
  int64_t poses = 0;
  int64_t images = 0;
  int64_t data_files = 0;  // image files copied or hard-linked
};

// Writes into `dst` the union of the sources' sensors.txt, rigs.txt,
// trajectories.txt and records_camera.txt (paths as "<prefix>/<path>"), and,
// when `copy_records_data`, their image files (hard links when possible,
// else copies; each file appears atomically). Other record types, features
// and reconstructions are not carried. A sensor id (or rig entry, or
// trajectory key) present in several sources must be identical in all, else
// InputError naming the source file; so must image paths after prefixing.
// Which images a merge keeps; trajectories.txt then only holds their poses.
struct ImageSelection {
  // Non-empty: only the images whose (prefixed) path matches it whole (e.g. the
  // mapping or the query sequences of one ground-truth kapture).
  std::string regex;
  // Of those, one image in every `sample_every` of each camera in time order
  // (the 1st, the N+1-th, ...): a sparse map of one recording.
  int sample_every = 1;
  // Keep the other N-1 of every N instead: the images that sparse map leaves
  // out, localized as queries. Together the two selections partition the images.
  bool sample_rest = false;
};

MergeReport MergeCameraKaptures(const std::vector<MergeSource>& sources, const fs::path& dst,
                                bool copy_records_data, const ImageSelection& select = {});

}  // namespace locforge::colmap_stages

#endif  // LOCFORGE_PLUGINS_SOURCE_KAPTURE_FOLDER_KAPTURE_MERGE_H_

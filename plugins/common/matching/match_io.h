// What the per-pair matching stages (matches/mutual_nn, verify/*) share:
// items "image1,image2" (image1 < image2; kapture paths cannot hold a comma),
// the pairs file, the local features and matches artifacts, the cameras and
// poses of the images, the common ports.
#ifndef LOCFORGE_PLUGINS_COMMON_MATCHING_MATCH_IO_H_
#define LOCFORGE_PLUGINS_COMMON_MATCHING_MATCH_IO_H_

#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "locforge/camera.h"
#include "locforge/kapture/csv.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "locforge/pose.h"

namespace locforge::matching {

namespace k = locforge::kapture;

inline std::pair<std::string, std::string> SplitItem(const std::string& item) {
  const size_t comma = item.find(',');
  if (comma == std::string::npos) throw Error("bad item '" + item + "'");
  return {item.substr(0, comma), item.substr(comma + 1)};
}

inline std::string MakeItem(const std::string& a, const std::string& b) {
  return a < b ? a + "," + b : b + "," + a;
}

// pairs.txt (kapture-localization): "image1, image2[, score]" per line.
inline std::vector<std::string> ReadPairItems(const fs::path& folder) {
  const fs::path file = folder / "pairs.txt";
  k::CsvReader reader(file, "pairs.txt");
  std::set<std::string> items;
  k::CsvRow row;
  while (reader.Next(&row)) {
    k::CheckFieldCount(row, "pairs.txt", 2, 3, "query_image, map_image, score");
    if (row.fields[0].empty() || row.fields[1].empty())
      throw InputError("pairs.txt", row.line, row.fields[0].empty() ? "query_image" : "map_image", "empty");
    if (row.fields[0] == row.fields[1]) continue;  // an image with itself
    items.insert(MakeItem(row.fields[0], row.fields[1]));
  }
  return {items.begin(), items.end()};
}

// One type of local features in a kapture.local_features artifact.
struct FeatureFolder {
  std::string type;
  fs::path keypoints_dir, descriptors_dir;
  k::FeatureInfo keypoints, descriptors;

  static FeatureFolder Open(const fs::path& artifact) {
    k::Kapture kap(artifact);
    const auto sets = kap.FeatureSets(k::FeatureKind::kKeypoints);
    if (sets.size() != 1)
      throw InputError(artifact.string(), 0, "reconstruction/keypoints",
                       "expected one keypoints type, found " + std::to_string(sets.size()));
    FeatureFolder f;
    f.type = sets.front().type;
    f.keypoints_dir = sets.front().dir;
    f.keypoints = sets.front().info;
    if (kap.HasFeatureType(k::FeatureKind::kDescriptors, f.type)) {
      const auto& d = kap.GetFeatureSet(k::FeatureKind::kDescriptors, f.type);
      f.descriptors_dir = d.dir;
      f.descriptors = d.info;
    }
    if (f.keypoints.dsize < 2)
      throw InputError((f.keypoints_dir / "keypoints.txt").string(), 0, "dsize", "below 2");
    return f;
  }
  bool Has(const std::string& image) const {
    return fs::exists(SafeJoin(keypoints_dir, image + ".kpt", "pairs.txt"));
  }
  std::vector<Eigen::Vector2d> Keypoints(const std::string& image) const {
    const auto a = k::ReadFeatureFile(SafeJoin(keypoints_dir, image + ".kpt", "pairs.txt"),
                                      keypoints.dtype, keypoints.dsize);
    std::vector<Eigen::Vector2d> out(a.rows);
    for (int64_t r = 0; r < a.rows; ++r) out[r] = {a.At(r, 0), a.At(r, 1)};
    return out;
  }
  k::FeatureArray Descriptors(const std::string& image) const {
    if (descriptors_dir.empty())
      throw InputError(keypoints_dir.string(), 0, "descriptors", "no descriptors of type '" + type + "'");
    return k::ReadFeatureFile(SafeJoin(descriptors_dir, image + ".desc", "pairs.txt"),
                              descriptors.dtype, descriptors.dsize);
  }
};

// The map features and optionally the queries' (a second artifact).
struct Features {
  FeatureFolder map;
  std::optional<FeatureFolder> query;

  static Features Open(RunContext& ctx) {
    Features f{FeatureFolder::Open(ctx.Input("features")), std::nullopt};
    if (ctx.HasInput("query_features")) {
      f.query = FeatureFolder::Open(ctx.Input("query_features"));
      if (f.query->type != f.map.type)
        throw InputError(ctx.Input("query_features").string(), 0, "reconstruction/keypoints",
                         "query keypoints type '" + f.query->type + "' differs from the map's '" +
                             f.map.type + "': matches need one type");
    }
    return f;
  }
  const FeatureFolder& Of(const std::string& image) const {
    if (query && query->Has(image)) return *query;
    if (!map.Has(image))
      throw InputError("pairs", 0, "image", "no keypoints of type '" + map.type + "' for '" + image + "'");
    return map;
  }
};

// Cameras and poses of the images of one or two datasets.
struct ImageGeometry {
  struct Entry {
    Camera camera;
    bool has_camera = false;
    std::optional<Pose> pose;
  };
  std::map<std::string, Entry> images;

  void Add(const fs::path& root) {
    k::Kapture kap(root);
    kap.ForEachDataRecord("camera", [&](const k::DataRecord& r) {
      Entry e;
      const k::Sensor* s = kap.sensors().Find(r.device_id);
      if (s && s->camera && s->camera->model != CameraModelId::kUnknown) {
        e.camera = *s->camera;
        e.has_camera = true;
      }
      e.pose = kap.DevicePose(r.timestamp, r.device_id);
      images.emplace(r.path, e);
    });
  }
  const Entry* Find(const std::string& image) const {
    auto it = images.find(image);
    return it == images.end() ? nullptr : &it->second;
  }
};

struct MatchesFolder {
  std::string type;
  fs::path root;
  static MatchesFolder Open(const fs::path& artifact) {
    k::Kapture kap(artifact);
    const auto types = kap.MatchesTypes();
    if (types.size() != 1)
      throw InputError(artifact.string(), 0, "reconstruction/matches",
                       "expected one keypoints type, found " + std::to_string(types.size()));
    return {types.front(), artifact};
  }
};

inline const PortMeta kFeaturesPort{"features", "kapture.local_features", "local features of the map (or all) images"};
inline const PortMeta kQueryFeaturesPort{"query_features", "kapture.local_features",
                                  "local features of the query images, when in another artifact",
                                  LF_PORT_OPTIONAL};
inline const PortMeta kMatchesOut{"matches", "kapture.matches", "matches per image pair"};

}  // namespace locforge::matching

#endif  // LOCFORGE_PLUGINS_COMMON_MATCHING_MATCH_IO_H_

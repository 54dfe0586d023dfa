// Reading the artifacts of image retrieval, shared by the global and pairs
// stages: the camera images of a dataset, one type of global features.
#ifndef LOCFORGE_PLUGINS_COMMON_RETRIEVAL_GLOBAL_FEATURES_H_
#define LOCFORGE_PLUGINS_COMMON_RETRIEVAL_GLOBAL_FEATURES_H_

#include <Eigen/Core>
#include <string>
#include <vector>

#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"

namespace locforge::retrieval {

namespace k = locforge::kapture;

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

inline std::vector<std::string> CameraImages(const fs::path& dataset) {
  return k::Kapture(dataset).CameraImages();
}

// One type of global features in a kapture.global_features artifact.
struct GlobalFeatures {
  std::string type;
  fs::path dir;
  k::FeatureInfo info;
  std::vector<std::string> images;

  static GlobalFeatures Open(const fs::path& artifact) {
    k::Kapture kap(artifact);
    const auto sets = kap.FeatureSets(k::FeatureKind::kGlobalFeatures);
    if (sets.size() != 1)
      throw InputError(artifact.string(), 0, "reconstruction/global_features",
                       "expected one global features type, found " + std::to_string(sets.size()));
    GlobalFeatures g{sets.front().type, sets.front().dir, sets.front().info, {}};
    g.images = kap.FeatureImages(k::FeatureKind::kGlobalFeatures, g.type);
    return g;
  }
  // Rows of unit L2 norm, in the order of `names`.
  RowMatrix Read(const std::vector<std::string>& names) const {
    RowMatrix m(static_cast<int64_t>(names.size()), info.dsize);
    for (size_t i = 0; i < names.size(); ++i) {
      const auto a = k::ReadFeatureFile(SafeJoin(dir, names[i] + ".gfeat"), info.dtype, info.dsize,
                                        type + "/" + names[i] + ".gfeat");
      if (a.rows != 1)
        throw InputError(type + "/" + names[i] + ".gfeat", 0, "", std::to_string(a.rows) + " rows, expected 1");
      for (int64_t c = 0; c < info.dsize; ++c) m(i, c) = static_cast<float>(a.At(0, c));
      const float n = m.row(i).norm();
      if (n > 0) m.row(i) /= n;
    }
    return m;
  }
};

}  // namespace locforge::retrieval

#endif  // LOCFORGE_PLUGINS_COMMON_RETRIEVAL_GLOBAL_FEATURES_H_

// Writing kapture features and matches (kapture.h).
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

}  // namespace locforge::kapture

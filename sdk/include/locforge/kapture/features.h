// kapture binary feature files (kapture/io/features.py): keypoints (.kpt),
// descriptors (.desc), global features (.gfeat) and matches (.matches).
//
// Each is a raw little-endian C-order array of N x dsize values of one numpy
// dtype, no header; the type folder's keypoints.txt / descriptors.txt /
// global_features.txt gives dtype and dsize. Matches are float64 N x 3:
// (keypoint index in image 1, keypoint index in image 2, score), stored once
// per pair under the lexicographically smaller image name.
#ifndef LOCFORGE_KAPTURE_FEATURES_H_
#define LOCFORGE_KAPTURE_FEATURES_H_

#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#include "locforge/error.h"
#include "locforge/fs.h"

namespace locforge::kapture {

enum class DType {
  kUint8,
  kInt8,
  kUint16,
  kInt16,
  kUint32,
  kInt32,
  kUint64,
  kInt64,
  kFloat16,
  kFloat32,
  kFloat64,
};

// numpy names: "uint8", "int32", "float16", "float32", "float64", ...;
// also numpy's aliases "float" and "double" (float64), "half" (float16),
// "single" (float32), "int" (int64), "ubyte"/"byte", and "np."/"numpy."
// prefixes. Returns false when unknown.
bool ParseDType(const std::string& name, DType* dtype);

// True for a usable feature type name, i.e. one folder under
// reconstruction/<kind>/ (not empty, no '/', '\\' or ',', not "." or "..").
bool IsFeatureTypeName(const std::string& name);
// The canonical numpy name ("float32").
const char* DTypeName(DType dtype);
size_t DTypeSize(DType dtype);

enum class FeatureKind { kKeypoints, kDescriptors, kGlobalFeatures };
// "keypoints", "descriptors", "global_features": the folder and .txt name.
const char* FeatureKindFolder(FeatureKind kind);
// ".kpt", ".desc", ".gfeat".
const char* FeatureKindExtension(FeatureKind kind);

// The one data line of keypoints.txt / descriptors.txt / global_features.txt.
struct FeatureInfo {
  FeatureKind kind = FeatureKind::kKeypoints;
  std::string name;        // extractor name, e.g. "SIFT", "r2d2"
  std::string dtype_name;  // as in the file ("float" stays "float")
  DType dtype = DType::kFloat32;
  int64_t dsize = 0;             // values per row
  std::string keypoints_type;    // descriptors only
  std::string metric_type;       // descriptors and global features, e.g. "L2"
};

// An N x dsize array of one dtype, bytes as in the file.
struct FeatureArray {
  DType dtype = DType::kFloat32;
  int64_t dsize = 0;
  int64_t rows = 0;
  std::vector<uint8_t> bytes;  // rows * dsize * DTypeSize(dtype)

  // Typed view; throws Error when T does not match dtype.
  template <class T>
  const T* data() const {
    CheckType(sizeof(T), std::is_floating_point<T>::value, std::is_signed<T>::value);
    return reinterpret_cast<const T*>(bytes.data());
  }
  // Any element as double (float16 converted), row-major.
  double At(int64_t row, int64_t col) const;

  template <class T>
  static FeatureArray From(DType dtype, int64_t dsize, const std::vector<T>& values) {
    FeatureArray a;
    a.dtype = dtype;
    a.dsize = dsize;
    a.rows = dsize > 0 ? static_cast<int64_t>(values.size()) / dsize : 0;
    a.CheckType(sizeof(T), std::is_floating_point<T>::value, std::is_signed<T>::value);
    if (dsize <= 0 || static_cast<int64_t>(values.size()) % dsize != 0)
      throw Error("FeatureArray: " + std::to_string(values.size()) +
                  " values are not a whole number of rows of " + std::to_string(dsize));
    a.bytes.resize(values.size() * sizeof(T));
    if (!values.empty()) std::memcpy(a.bytes.data(), values.data(), a.bytes.size());
    return a;
  }

 private:
  void CheckType(size_t size, bool floating, bool is_signed) const;
};

// Reads a feature file of `dtype` with rows of `dsize` values. Throws
// InputError naming `display_name` (default: the path) when the file is
// missing, or its size is not a multiple of dsize * sizeof(dtype) (a
// truncated file, or the wrong dsize/dtype in the .txt).
FeatureArray ReadFeatureFile(const fs::path& path, DType dtype, int64_t dsize,
                             const std::string& display_name = "");
// The same check on bytes read elsewhere (an entry of a tar-packed type,
// tar.h); `display_name` names it ("<archive>: entry '<name>'").
FeatureArray FeatureArrayFromBytes(std::vector<uint8_t> bytes, DType dtype, int64_t dsize,
                                   const std::string& display_name);
// Writes the bytes exactly, atomically.
void WriteFeatureFile(const fs::path& path, const FeatureArray& array);

struct Match {
  double index1 = 0;  // keypoint index in the first image (float64 in the file)
  double index2 = 0;
  double score = 0;
};
std::vector<Match> MatchesFromArray(const FeatureArray& array);
FeatureArray MatchesToArray(const std::vector<Match>& matches);

}  // namespace locforge::kapture

#endif  // LOCFORGE_KAPTURE_FEATURES_H_

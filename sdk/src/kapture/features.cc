#include "locforge/kapture/features.h"

#include <cmath>
#include <fstream>

namespace locforge::kapture {

namespace {

struct DTypeEntry {
  DType dtype;
  const char* name;
  size_t size;
  bool floating;
  bool is_signed;
};

const DTypeEntry kDTypes[] = {
    {DType::kUint8, "uint8", 1, false, false},     {DType::kInt8, "int8", 1, false, true},
    {DType::kUint16, "uint16", 2, false, false},   {DType::kInt16, "int16", 2, false, true},
    {DType::kUint32, "uint32", 4, false, false},   {DType::kInt32, "int32", 4, false, true},
    {DType::kUint64, "uint64", 8, false, false},   {DType::kInt64, "int64", 8, false, true},
    {DType::kFloat16, "float16", 2, true, true},   {DType::kFloat32, "float32", 4, true, true},
    {DType::kFloat64, "float64", 8, true, true},
};

const DTypeEntry& Entry(DType dtype) {
  for (const DTypeEntry& e : kDTypes)
    if (e.dtype == dtype) return e;
  throw Error("unknown dtype id " + std::to_string(static_cast<int>(dtype)));
}

double HalfToDouble(uint16_t h) {
  const int sign = (h >> 15) & 1;
  const int exponent = (h >> 10) & 0x1f;
  const int mantissa = h & 0x3ff;
  double v;
  if (exponent == 0) {
    v = std::ldexp(mantissa, -24);
  } else if (exponent == 31) {
    v = mantissa ? std::nan("") : HUGE_VAL;
  } else {
    v = std::ldexp(mantissa + 1024, exponent - 25);
  }
  return sign ? -v : v;
}

template <class T>
T Load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

}  // namespace

bool ParseDType(const std::string& raw, DType* dtype) {
  std::string name = raw;
  for (const char* prefix : {"numpy.", "np."})
    if (name.rfind(prefix, 0) == 0) name = name.substr(std::strlen(prefix));
  // numpy's byte-order/kind codes, little-endian or native only.
  static const struct {
    const char* alias;
    DType dtype;
  } kAliases[] = {
      {"float", DType::kFloat64},  {"double", DType::kFloat64}, {"float_", DType::kFloat64},
      {"single", DType::kFloat32}, {"half", DType::kFloat16},   {"int", DType::kInt64},
      {"int_", DType::kInt64},     {"ubyte", DType::kUint8},    {"byte", DType::kInt8},
      {"uint", DType::kUint64},    {"<f2", DType::kFloat16},    {"<f4", DType::kFloat32},
      {"<f8", DType::kFloat64},    {"f2", DType::kFloat16},     {"f4", DType::kFloat32},
      {"f8", DType::kFloat64},     {"|u1", DType::kUint8},      {"u1", DType::kUint8},
      {"|i1", DType::kInt8},       {"i1", DType::kInt8},        {"<u2", DType::kUint16},
      {"<i2", DType::kInt16},      {"<u4", DType::kUint32},     {"<i4", DType::kInt32},
      {"<u8", DType::kUint64},     {"<i8", DType::kInt64},
  };
  for (const DTypeEntry& e : kDTypes)
    if (name == e.name) {
      *dtype = e.dtype;
      return true;
    }
  for (const auto& a : kAliases)
    if (name == a.alias) {
      *dtype = a.dtype;
      return true;
    }
  return false;
}

const char* DTypeName(DType dtype) { return Entry(dtype).name; }
size_t DTypeSize(DType dtype) { return Entry(dtype).size; }

const char* FeatureKindFolder(FeatureKind kind) {
  switch (kind) {
    case FeatureKind::kKeypoints: return "keypoints";
    case FeatureKind::kDescriptors: return "descriptors";
    case FeatureKind::kGlobalFeatures: return "global_features";
  }
  return "";
}

const char* FeatureKindExtension(FeatureKind kind) {
  switch (kind) {
    case FeatureKind::kKeypoints: return ".kpt";
    case FeatureKind::kDescriptors: return ".desc";
    case FeatureKind::kGlobalFeatures: return ".gfeat";
  }
  return "";
}

void FeatureArray::CheckType(size_t size, bool floating, bool is_signed) const {
  const DTypeEntry& e = Entry(dtype);
  // float16 has no C++ type: read it as uint16_t (raw bits) or through At().
  const bool half_as_bits = dtype == DType::kFloat16 && size == 2 && !floating && !is_signed;
  if (half_as_bits) return;
  if (e.size != size || e.floating != floating || e.is_signed != is_signed)
    throw Error(std::string("feature array holds ") + e.name +
                ", the requested element type does not match");
}

double FeatureArray::At(int64_t row, int64_t col) const {
  if (row < 0 || row >= rows || col < 0 || col >= dsize)
    throw Error("feature array index (" + std::to_string(row) + ", " + std::to_string(col) +
                ") out of range " + std::to_string(rows) + " x " + std::to_string(dsize));
  const size_t size = DTypeSize(dtype);
  const uint8_t* p = bytes.data() + static_cast<size_t>(row * dsize + col) * size;
  switch (dtype) {
    case DType::kUint8: return Load<uint8_t>(p);
    case DType::kInt8: return Load<int8_t>(p);
    case DType::kUint16: return Load<uint16_t>(p);
    case DType::kInt16: return Load<int16_t>(p);
    case DType::kUint32: return Load<uint32_t>(p);
    case DType::kInt32: return Load<int32_t>(p);
    case DType::kUint64: return static_cast<double>(Load<uint64_t>(p));
    case DType::kInt64: return static_cast<double>(Load<int64_t>(p));
    case DType::kFloat16: return HalfToDouble(Load<uint16_t>(p));
    case DType::kFloat32: return Load<float>(p);
    case DType::kFloat64: return Load<double>(p);
  }
  return 0;
}

namespace {

// The size check shared by files and archive entries.
void CheckFeatureSize(uintmax_t size, DType dtype, int64_t dsize, const std::string& name) {
  if (dsize <= 0) throw InputError(name, 0, "dsize", "must be positive, got " + std::to_string(dsize));
  const uintmax_t row_bytes = static_cast<uintmax_t>(dsize) * DTypeSize(dtype);
  if (size % row_bytes != 0)
    throw InputError(name, 0, "",
                     "size " + std::to_string(size) + " bytes is not a multiple of dsize " +
                         std::to_string(dsize) + " x sizeof(" + DTypeName(dtype) + ") = " +
                         std::to_string(row_bytes) +
                         " (truncated file, or wrong dtype/dsize in the type's .txt)");
}

}  // namespace

FeatureArray FeatureArrayFromBytes(std::vector<uint8_t> bytes, DType dtype, int64_t dsize,
                                   const std::string& display_name) {
  CheckFeatureSize(bytes.size(), dtype, dsize, display_name);
  FeatureArray a;
  a.dtype = dtype;
  a.dsize = dsize;
  a.rows = static_cast<int64_t>(bytes.size() / (static_cast<size_t>(dsize) * DTypeSize(dtype)));
  a.bytes = std::move(bytes);
  return a;
}

FeatureArray ReadFeatureFile(const fs::path& path, DType dtype, int64_t dsize,
                             const std::string& display_name) {
  const std::string name = display_name.empty() ? path.string() : display_name;
  if (dsize <= 0) throw InputError(name, 0, "dsize", "must be positive, got " + std::to_string(dsize));
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(name, 0, "", "missing feature file");
  const uintmax_t size = fs::file_size(path, ec);
  if (ec) throw InputError(name, 0, "", "cannot read size: " + ec.message());
  CheckFeatureSize(size, dtype, dsize, name);
  std::vector<uint8_t> bytes(static_cast<size_t>(size));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(name, 0, "", "cannot open file");
  if (size > 0) in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(size));
  if (static_cast<uintmax_t>(in.gcount()) != size)
    throw InputError(name, 0, "", "short read: the file changed while reading");
  return FeatureArrayFromBytes(std::move(bytes), dtype, dsize, name);
}

void WriteFeatureFile(const fs::path& path, const FeatureArray& array) {
  const size_t expected = static_cast<size_t>(array.rows * array.dsize) * DTypeSize(array.dtype);
  if (array.bytes.size() != expected)
    throw Error("feature array for " + path.string() + " has " +
                std::to_string(array.bytes.size()) + " bytes, expected " +
                std::to_string(expected));
  WriteFileAtomic(path, std::string_view(reinterpret_cast<const char*>(array.bytes.data()),
                                         array.bytes.size()));
}

std::vector<Match> MatchesFromArray(const FeatureArray& array) {
  if (array.dtype != DType::kFloat64 || array.dsize != 3)
    throw Error(std::string("matches must be float64 N x 3, got ") + DTypeName(array.dtype) +
                " N x " + std::to_string(array.dsize));
  std::vector<Match> out(static_cast<size_t>(array.rows));
  const double* v = array.data<double>();
  for (size_t i = 0; i < out.size(); ++i) out[i] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
  return out;
}

FeatureArray MatchesToArray(const std::vector<Match>& matches) {
  std::vector<double> v;
  v.reserve(matches.size() * 3);
  for (const Match& m : matches) {
    v.push_back(m.index1);
    v.push_back(m.index2);
    v.push_back(m.score);
  }
  return FeatureArray::From(DType::kFloat64, 3, v);
}

bool IsFeatureTypeName(const std::string& name) {
  return !name.empty() && name.find_first_of("/\\,") == std::string::npos && name != "." &&
         name != "..";
}

}  // namespace locforge::kapture

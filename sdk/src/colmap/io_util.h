// Private helpers of locforge_colmap: tokenising text lines, parsing numbers
// with errors that name file, line and field, and a bounds-checked binary
// reader. Not installed.
#ifndef LOCFORGE_SDK_SRC_COLMAP_IO_UTIL_H_
#define LOCFORGE_SDK_SRC_COLMAP_IO_UTIL_H_

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

#include "locforge/error.h"

namespace locforge::colmap::internal {

// Whitespace-separated tokens of a line (COLMAP separates with single
// spaces; tabs and repeated spaces are tolerated).
std::vector<std::string_view> Tokenize(std::string_view line);
std::string_view Trim(std::string_view s);

// Where a text field comes from, for error messages.
struct TextPos {
  const std::string& file;
  int64_t line;
};

double ParseDouble(std::string_view token, const TextPos& pos, const std::string& field);
uint64_t ParseUint(std::string_view token, const TextPos& pos, const std::string& field,
                   uint64_t max_value);
int64_t ParseInt(std::string_view token, const TextPos& pos, const std::string& field);

// Little-endian binary reader over a file that refuses to read past its end
// and names the field and byte offset it was reading.
class BinaryReader {
 public:
  explicit BinaryReader(const std::filesystem::path& path);
  template <typename T>
  T Read(const std::string& field) {
    T value;
    ReadBytes(&value, sizeof(T), field);
    return value;  // host is little-endian (static_assert in the .cc)
  }
  std::string ReadNulTerminated(const std::string& field);
  void ReadBytes(void* dst, size_t n, const std::string& field);
  // Refuses a record count that cannot fit in the bytes left (each record at
  // least `min_record_bytes`), so a corrupt count never triggers a huge
  // allocation.
  void CheckCount(uint64_t count, uint64_t min_record_bytes, const std::string& field) const;
  uint64_t offset() const { return offset_; }
  uint64_t remaining() const { return size_ - offset_; }
  const std::string& name() const { return name_; }
  [[noreturn]] void Fail(const std::string& field, const std::string& what) const;

 private:
  std::ifstream in_;
  std::string name_;
  uint64_t size_ = 0;
  uint64_t offset_ = 0;
};

template <typename T>
void WriteLE(std::ostream& out, const T& value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}

}  // namespace locforge::colmap::internal

#endif  // LOCFORGE_SDK_SRC_COLMAP_IO_UTIL_H_

#include "io_util.h"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>

namespace locforge::colmap::internal {

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__,
              "COLMAP binary files are little-endian; big-endian hosts need byte swaps");

namespace {
bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }
}  // namespace

std::string_view Trim(std::string_view s) {
  while (!s.empty() && IsSpace(s.front())) s.remove_prefix(1);
  while (!s.empty() && IsSpace(s.back())) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> Tokenize(std::string_view line) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && IsSpace(line[i])) ++i;
    const size_t start = i;
    while (i < line.size() && !IsSpace(line[i])) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

double ParseDouble(std::string_view token, const TextPos& pos, const std::string& field) {
  // strtod (not from_chars) so "nan"/"inf" and every form COLMAP prints parse.
  const std::string s(token);
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size()) {
    throw InputError(pos.file, pos.line, field, "expected a number, got '" + s + "'");
  }
  if (errno == ERANGE && std::isinf(v)) {
    throw InputError(pos.file, pos.line, field, "number out of range: '" + s + "'");
  }
  return v;
}

uint64_t ParseUint(std::string_view token, const TextPos& pos, const std::string& field,
                   uint64_t max_value) {
  uint64_t v = 0;
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  if (token.empty() || ec != std::errc() || ptr != token.data() + token.size()) {
    throw InputError(pos.file, pos.line, field,
                     "expected a non-negative integer, got '" + std::string(token) + "'");
  }
  if (v > max_value) {
    throw InputError(pos.file, pos.line, field,
                     "value " + std::string(token) + " exceeds " + std::to_string(max_value));
  }
  return v;
}

int64_t ParseInt(std::string_view token, const TextPos& pos, const std::string& field) {
  int64_t v = 0;
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  if (token.empty() || ec != std::errc() || ptr != token.data() + token.size()) {
    throw InputError(pos.file, pos.line, field,
                     "expected an integer, got '" + std::string(token) + "'");
  }
  return v;
}

BinaryReader::BinaryReader(const std::filesystem::path& path)
    : in_(path, std::ios::binary), name_(path.string()) {
  if (!in_) throw InputError(name_, 0, "", "cannot open file");
  std::error_code ec;
  size_ = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(name_, 0, "", "cannot read file size: " + ec.message());
}

void BinaryReader::Fail(const std::string& field, const std::string& what) const {
  throw InputError(name_ + " @byte " + std::to_string(offset_), 0, field, what);
}

void BinaryReader::ReadBytes(void* dst, size_t n, const std::string& field) {
  if (n > remaining()) {
    Fail(field, "file truncated: needs " + std::to_string(n) + " bytes, " +
                    std::to_string(remaining()) + " left");
  }
  in_.read(static_cast<char*>(dst), static_cast<std::streamsize>(n));
  if (!in_) Fail(field, "read error");
  offset_ += n;
}

std::string BinaryReader::ReadNulTerminated(const std::string& field) {
  std::string s;
  for (;;) {
    char c;
    if (remaining() == 0) Fail(field, "file truncated inside a NUL-terminated string");
    ReadBytes(&c, 1, field);
    if (c == '\0') return s;
    s.push_back(c);
  }
}

void BinaryReader::CheckCount(uint64_t count, uint64_t min_record_bytes,
                              const std::string& field) const {
  if (min_record_bytes > 0 && count > remaining() / min_record_bytes) {
    Fail(field, "count " + std::to_string(count) + " cannot fit in the " +
                    std::to_string(remaining()) + " bytes left (file truncated or corrupt)");
  }
}

}  // namespace locforge::colmap::internal

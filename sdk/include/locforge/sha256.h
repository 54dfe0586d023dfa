// SHA-256 (FIPS 180-4): the cache keys of graph nodes, checksums of outputs.
#ifndef LOCFORGE_SHA256_H_
#define LOCFORGE_SHA256_H_

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace locforge {

class Sha256 {
 public:
  Sha256();
  void Update(std::string_view data);
  // Lower-case hex of the 32-byte digest. The object is spent afterwards.
  std::string HexDigest();

 private:
  void Block(const uint8_t* p);
  std::array<uint32_t, 8> h_;
  std::array<uint8_t, 64> buffer_{};
  size_t buffered_ = 0;
  uint64_t total_bytes_ = 0;
};

std::string Sha256Hex(std::string_view data);
// SHA-256 hex of a file's content, read in blocks; throws Error naming the
// file when it cannot be read.
std::string Sha256FileHex(const std::filesystem::path& file);

}  // namespace locforge

#endif  // LOCFORGE_SHA256_H_

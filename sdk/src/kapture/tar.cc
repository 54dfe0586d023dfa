// A strict POSIX ustar reader for kapture's tar-packed features (tar.h).
#include "locforge/kapture/tar.h"

#include <algorithm>
#include <cstring>
#include <fstream>

#include "locforge/error.h"

namespace locforge::kapture {

namespace {

constexpr uint64_t kBlock = 512;

struct Header {
  std::string name, size_text, checksum_text, magic;
  char type = '0';
};

std::string CString(const char* p, size_t n) {
  return std::string(p, strnlen(p, n));
}

Header SplitHeader(const char* b) {
  Header h;
  h.name = CString(b + 0, 100);
  h.size_text = CString(b + 124, 12);
  h.checksum_text = CString(b + 148, 8);
  h.type = b[156];
  h.magic = std::string(b + 257, 6);
  const std::string prefix = CString(b + 345, 155);
  if (h.magic == std::string("ustar\0", 6) && !prefix.empty()) h.name = prefix + "/" + h.name;
  return h;
}

bool ParseDigits(const std::string& text, uint64_t base, uint64_t* value) {
  const size_t b = text.find_first_not_of(' ');
  if (b == std::string::npos) return false;
  const size_t e = text.find_last_not_of(' ');
  *value = 0;
  for (size_t i = b; i <= e; ++i) {
    const uint64_t digit = static_cast<uint64_t>(text[i] - '0');
    if (text[i] < '0' || digit >= base || *value > (UINT64_MAX - digit) / base) return false;
    *value = *value * base + digit;
  }
  return true;
}

// The header checksum: every byte summed with the checksum field as spaces,
// bytes unsigned (POSIX) or, as some old tars wrote it, signed.
int64_t Checksum(const char* b, bool signed_bytes) {
  int64_t sum = 0;
  for (uint64_t i = 0; i < kBlock; ++i)
    sum += (i >= 148 && i < 156) ? ' '
           : signed_bytes        ? static_cast<signed char>(b[i])
                                 : static_cast<unsigned char>(b[i]);
  return sum;
}

bool IsZeroBlock(const char* b) {
  return std::all_of(b, b + kBlock, [](char c) { return c == 0; });
}

// A name that stays inside the folder, "./" dropped; "" when refused.
std::string SafeEntryName(std::string name, std::string* why) {
  while (name.rfind("./", 0) == 0) name.erase(0, 2);
  while (!name.empty() && name.back() == '/') name.pop_back();
  if (name.empty()) *why = "empty name";
  else if (name[0] == '/') *why = "absolute name";
  else if (name.find('\\') != std::string::npos || name.find('\0') != std::string::npos)
    *why = "backslash or NUL in the name";
  else {
    size_t start = 0;
    while (start <= name.size()) {
      const size_t slash = std::min(name.find('/', start), name.size());
      const std::string part = name.substr(start, slash - start);
      if (part.empty() || part == "." || part == "..") {
        *why = "name climbs out of the folder or has an empty component";
        break;
      }
      start = slash + 1;
    }
  }
  return why->empty() ? name : "";
}

// pax extended header records "<len> key=value\n": path and size are used.
void ParsePax(const std::string& data, std::string* path, std::string* size,
              const std::string& where) {
  size_t pos = 0;
  while (pos < data.size()) {
    const size_t space = data.find(' ', pos);
    uint64_t len = 0;
    if (space == std::string::npos || !ParseDigits(data.substr(pos, space - pos), 10, &len) ||
        len == 0 || pos + len > data.size() || data[pos + len - 1] != '\n')
      throw InputError(where + ": malformed pax extended header");
    const std::string record = data.substr(space + 1, pos + len - space - 2);
    const size_t eq = record.find('=');
    if (eq == std::string::npos) throw InputError(where + ": malformed pax record");
    if (record.compare(0, eq, "path") == 0) *path = record.substr(eq + 1);
    if (record.compare(0, eq, "size") == 0) *size = record.substr(eq + 1);
    pos += len;
  }
}

}  // namespace

namespace {

// Reads the archive block by block, bounds checked.
class BlockReader {
 public:
  BlockReader(const fs::path& path, const std::string& name) : in_(path, std::ios::binary), name_(name) {
    if (!in_) throw InputError(name, 0, "", "cannot open archive");
    std::error_code ec;
    size_ = fs::file_size(path, ec);
    if (ec) throw InputError(name, 0, "", "cannot read size: " + ec.message());
  }
  uint64_t size() const { return size_; }
  std::string Read(uint64_t offset, uint64_t n, const std::string& what) {
    if (offset > size_ || n > size_ - offset)
      throw InputError(name_, 0, "", what + ": runs past the end of the archive (truncated?)");
    std::string out(static_cast<size_t>(n), '\0');
    in_.seekg(static_cast<std::streamoff>(offset));
    in_.read(out.data(), static_cast<std::streamsize>(n));
    if (static_cast<uint64_t>(in_.gcount()) != n)
      throw InputError(name_, 0, "", what + ": short read");
    return out;
  }

 private:
  std::ifstream in_;
  std::string name_;
  uint64_t size_ = 0;
};

// Names and sizes carried over from pax / GNU long-name headers to the
// entry that follows them.
struct Pending {
  std::string path, size;
};

std::string Where(uint64_t pos, const std::string& name) {
  return "entry '" + name + "' (header at byte " + std::to_string(pos) + ")";
}

void CheckHeader(const char* block, const Header& h, uint64_t pos, const std::string& archive) {
  const bool posix = h.magic == std::string("ustar\0", 6);
  const bool gnu = h.magic == "ustar ";
  if (!posix && !gnu)
    throw InputError(archive, 0, "", Where(pos, h.name) + ": not a ustar header (bad magic)");
  uint64_t stored = 0;
  const bool parsed = ParseDigits(h.checksum_text, 8, &stored);
  if (!parsed || (static_cast<int64_t>(stored) != Checksum(block, false) &&
                  static_cast<int64_t>(stored) != Checksum(block, true)))
    throw InputError(archive, 0, "", Where(pos, h.name) + ": bad header checksum");
}

}  // namespace

TarArchive::TarArchive(const fs::path& path, const std::string& display_name)
    : path_(path), name_(display_name.empty() ? path.string() : display_name) {
  BlockReader reader(path, name_);
  Pending pending;
  uint64_t pos = 0;
  while (true) {
    if (pos >= reader.size())
      throw InputError(name_, 0, "", "no end-of-archive block (truncated archive?)");
    const std::string block = reader.Read(pos, kBlock, "header at byte " + std::to_string(pos));
    if (IsZeroBlock(block.data())) break;
    const Header h = SplitHeader(block.data());
    CheckHeader(block.data(), h, pos, name_);
    std::string name = !pending.path.empty() ? pending.path : h.name;
    const std::string where = Where(pos, name);
    uint64_t size = 0;
    if (!ParseDigits(pending.size.empty() ? h.size_text : pending.size,
                     pending.size.empty() ? 8 : 10, &size))
      throw InputError(name_, 0, "", where + ": bad size field");
    const uint64_t data = pos + kBlock;
    if (data > reader.size() || size > reader.size() - data)
      throw InputError(name_, 0, "", where + ": data runs past the end of the archive (truncated?)");
    pos = data + (size + kBlock - 1) / kBlock * kBlock;
    if (h.type == 'x' || h.type == 'L') {
      if (size > (1u << 20)) throw InputError(name_, 0, "", where + ": extended header too large");
      const std::string text = reader.Read(data, size, where);
      if (h.type == 'L') pending.path = CString(text.data(), text.size());
      else ParsePax(text, &pending.path, &pending.size, name_ + ": " + where);
      continue;
    }
    pending = Pending();
    if (h.type == 'g') continue;  // pax global header: nothing we use
    std::string why;
    name = SafeEntryName(name, &why);
    if (!why.empty()) throw InputError(name_, 0, "", where + ": " + why);
    if (h.type == '5') continue;  // a folder
    if (h.type != '0' && h.type != '\0' && h.type != '7')
      throw InputError(name_, 0, "", where + ": type '" + std::string(1, h.type) +
                                         "' (link, device or FIFO); only regular files and "
                                         "folders are read");
    entries_[name] = TarEntry{name, data, size};
  }
}

const TarEntry* TarArchive::Find(const std::string& name) const {
  const auto it = entries_.find(name);
  return it == entries_.end() ? nullptr : &it->second;
}

std::vector<uint8_t> TarArchive::Read(const TarEntry& entry) const {
  BlockReader reader(path_, name_);
  const std::string bytes = reader.Read(entry.offset, entry.size, "entry '" + entry.name + "'");
  return std::vector<uint8_t>(bytes.begin(), bytes.end());
}

}  // namespace locforge::kapture

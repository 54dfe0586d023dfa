#include "pcap.h"

#include "locforge/error.h"

namespace locforge::velodyne {

namespace {

constexpr uint32_t kMagicMicro = 0xa1b2c3d4, kMagicNano = 0xa1b23c4d;
constexpr uint32_t kPcapngMagic = 0x0a0d0d0a;
constexpr uint32_t kLinkEthernet = 1, kLinkRawIp = 101, kLinkLinuxSll = 113, kLinkRaw = 12;
constexpr uint32_t kMaxRecord = 256 * 1024;  // no link layer frame is larger

uint16_t BigEndian16(const unsigned char* p) { return static_cast<uint16_t>(p[0] << 8 | p[1]); }

uint32_t Swap32(uint32_t v) {
  return (v >> 24) | ((v >> 8) & 0xff00) | ((v << 8) & 0xff0000) | (v << 24);
}

}  // namespace

uint32_t PcapReader::U32(const unsigned char* p) const {
  const uint32_t v = static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 |
                     static_cast<uint32_t>(p[2]) << 16 | static_cast<uint32_t>(p[3]) << 24;
  return swapped_ ? Swap32(v) : v;
}

uint16_t PcapReader::U16(const unsigned char* p) const {
  const uint16_t v = static_cast<uint16_t>(p[0] | p[1] << 8);
  return swapped_ ? static_cast<uint16_t>(v >> 8 | v << 8) : v;
}

PcapReader::PcapReader(const std::filesystem::path& file) : file_(file), in_(file, std::ios::binary) {
  if (!in_) throw InputError(file.string(), 0, "", "cannot open the capture file");
  unsigned char h[24];
  if (!in_.read(reinterpret_cast<char*>(h), sizeof(h)))
    throw InputError(file.string(), 0, "", "shorter than a pcap file header (24 bytes)");
  const uint32_t magic = static_cast<uint32_t>(h[0]) | static_cast<uint32_t>(h[1]) << 8 |
                         static_cast<uint32_t>(h[2]) << 16 | static_cast<uint32_t>(h[3]) << 24;
  if (magic == kPcapngMagic)
    throw InputError(file.string(), 0, "",
                     "a pcapng file; convert it to classic pcap first: editcap -F pcap IN.pcapng OUT.pcap");
  if (magic == kMagicMicro || magic == kMagicNano) {
    swapped_ = false;
  } else if (Swap32(magic) == kMagicMicro || Swap32(magic) == kMagicNano) {
    swapped_ = true;
  } else {
    throw InputError(file.string(), 0, "", "not a pcap capture file (unknown magic number)");
  }
  nanoseconds_ = (swapped_ ? Swap32(magic) : magic) == kMagicNano;
  snap_length_ = U32(h + 16);
  link_type_ = U32(h + 20) & 0x0fffffff;  // the upper bits carry FCS information
  if (link_type_ != kLinkEthernet && link_type_ != kLinkRawIp && link_type_ != kLinkLinuxSll &&
      link_type_ != kLinkRaw)
    throw InputError(file.string(), 0, "link type",
                     "link type " + std::to_string(link_type_) +
                         " is not supported (Ethernet, Linux cooked capture or raw IP)");
  offset_ = sizeof(h);
}

bool PcapReader::Next(UdpPacket* packet) {
  std::string frame;
  while (true) {
    unsigned char r[16];
    const int64_t record_offset = offset_;
    if (!in_.read(reinterpret_cast<char*>(r), sizeof(r))) {
      if (in_.gcount() > 0) ++stats_.skipped;  // a truncated record header at the end
      return false;
    }
    offset_ += sizeof(r);
    const uint32_t seconds = U32(r), fraction = U32(r + 4), captured = U32(r + 8);
    if (captured > kMaxRecord || (snap_length_ > 0 && captured > snap_length_ && captured > 65535))
      throw InputError(file_.string(), 0, "byte " + std::to_string(record_offset),
                       "record of " + std::to_string(captured) + " bytes: the file is corrupt");
    frame.resize(captured);
    if (!in_.read(frame.data(), captured)) {
      ++stats_.skipped;  // the capture stopped in the middle of a record
      return false;
    }
    offset_ += captured;
    ++stats_.records;
    const auto* p = reinterpret_cast<const unsigned char*>(frame.data());
    size_t n = frame.size(), at = 0;
    uint16_t ethertype = 0x0800;
    if (link_type_ == kLinkEthernet) {
      if (n < 14) {
        ++stats_.skipped;
        continue;
      }
      ethertype = BigEndian16(p + 12);
      at = 14;
      while ((ethertype == 0x8100 || ethertype == 0x88a8) && at + 4 <= n) {  // VLAN tags
        ethertype = BigEndian16(p + at + 2);
        at += 4;
      }
    } else if (link_type_ == kLinkLinuxSll) {
      if (n < 16) {
        ++stats_.skipped;
        continue;
      }
      ethertype = BigEndian16(p + 14);
      at = 16;
    }
    if (ethertype != 0x0800 || at + 20 > n || (p[at] >> 4) != 4) {
      ++stats_.skipped;
      continue;
    }
    const size_t ip_header = (p[at] & 0x0f) * 4;
    const size_t ip_length = BigEndian16(p + at + 2);
    const bool fragment = (BigEndian16(p + at + 6) & 0x3fff) != 0;  // more fragments, or an offset
    if (ip_header < 20 || p[at + 9] != 17 || fragment || at + ip_length > n || ip_length < ip_header + 8) {
      ++stats_.skipped;
      continue;
    }
    const size_t udp = at + ip_header;
    const size_t udp_length = BigEndian16(p + udp + 4);
    if (udp_length < 8 || udp + udp_length > at + ip_length) {
      ++stats_.skipped;
      continue;
    }
    packet->capture_time = seconds + fraction * (nanoseconds_ ? 1e-9 : 1e-6);
    packet->source_port = BigEndian16(p + udp);
    packet->destination_port = BigEndian16(p + udp + 2);
    packet->payload.assign(frame, udp + 8, udp_length - 8);
    packet->file_offset = record_offset;
    ++stats_.udp;
    return true;
  }
}

}  // namespace locforge::velodyne

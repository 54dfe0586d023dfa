// Reading UDP payloads out of a classic pcap capture file (tcpdump,
// Wireshark's "pcap" format, VeloView recordings). The format is read
// directly: a 24-byte file header (magic a1b2c3d4 or a1b23c4d for
// nanosecond captures, either byte order), then per packet a 16-byte
// record header and the captured bytes. Link layers: Ethernet (with 802.1Q
// VLAN tags), Linux cooked capture (SLL) and raw IPv4. IPv4 + UDP only;
// fragments and other protocols are counted and skipped. pcapng files are
// refused with what to do.
#ifndef LOCFORGE_PLUGINS_SOURCE_VELODYNE_PCAP_PCAP_H_
#define LOCFORGE_PLUGINS_SOURCE_VELODYNE_PCAP_PCAP_H_

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

namespace locforge::velodyne {

struct UdpPacket {
  double capture_time = 0;  // s since the epoch, from the record header
  uint16_t source_port = 0, destination_port = 0;
  std::string payload;
  int64_t file_offset = 0;  // of the record header, for messages
};

struct PcapStats {
  int64_t records = 0;        // every record of the file
  int64_t udp = 0;            // IPv4 UDP datagrams
  int64_t skipped = 0;        // other link types, protocols, fragments, truncated captures
};

class PcapReader {
 public:
  // Throws InputError naming the file when it is not a classic pcap file.
  explicit PcapReader(const std::filesystem::path& file);
  // The next UDP datagram; false at the end of the file. A truncated last
  // record ends the file (counted as skipped); a malformed record header
  // throws InputError naming the file and byte offset.
  bool Next(UdpPacket* packet);
  const PcapStats& stats() const { return stats_; }
  uint32_t link_type() const { return link_type_; }

 private:
  uint32_t U32(const unsigned char* p) const;
  uint16_t U16(const unsigned char* p) const;

  std::filesystem::path file_;
  std::ifstream in_;
  bool swapped_ = false;
  bool nanoseconds_ = false;
  uint32_t link_type_ = 0;
  uint32_t snap_length_ = 0;
  int64_t offset_ = 0;
  PcapStats stats_;
};

}  // namespace locforge::velodyne

#endif  // LOCFORGE_PLUGINS_SOURCE_VELODYNE_PCAP_PCAP_H_

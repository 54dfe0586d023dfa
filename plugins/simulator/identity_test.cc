// The simulator's outputs, byte for byte: three short recordings (people,
// cameras, masks and both LiDARs on; a tiny, a small and a large floor) hashed
// file by file (SHA-256) against testdata/recording_sha256.txt. Any change of
// any output byte fails here, so speed work on the ray casting must keep every
// image, mask, point cloud and text file identical. When an output change is
// intended, regenerate the sums (the failure message says how) and say so in
// the README.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "dataset.h"
#include "testing.h"

namespace locforge::sim {
namespace {

// FIPS 180-4 SHA-256 of a byte string, as lowercase hex.
std::string Sha256(const std::string& data) {
  static const uint32_t k[64] = {
      0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
      0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
      0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
      0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
      0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
      0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
      0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
      0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2};
  uint32_t h[8] = {0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a, 0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19};
  std::string m = data;
  const uint64_t bits = static_cast<uint64_t>(data.size()) * 8;
  m.push_back(static_cast<char>(0x80));
  while (m.size() % 64 != 56) m.push_back(0);
  for (int i = 7; i >= 0; --i) m.push_back(static_cast<char>((bits >> (8 * i)) & 0xff));
  const auto rotr = [](uint32_t x, int n) { return (x >> n) | (x << (32 - n)); };
  for (size_t block = 0; block < m.size(); block += 64) {
    uint32_t w[64];
    for (int i = 0; i < 16; ++i)
      w[i] = uint32_t(uint8_t(m[block + 4 * i])) << 24 | uint32_t(uint8_t(m[block + 4 * i + 1])) << 16 |
             uint32_t(uint8_t(m[block + 4 * i + 2])) << 8 | uint32_t(uint8_t(m[block + 4 * i + 3]));
    for (int i = 16; i < 64; ++i) {
      const uint32_t s0 = rotr(w[i - 15], 7) ^ rotr(w[i - 15], 18) ^ (w[i - 15] >> 3);
      const uint32_t s1 = rotr(w[i - 2], 17) ^ rotr(w[i - 2], 19) ^ (w[i - 2] >> 10);
      w[i] = w[i - 16] + s0 + w[i - 7] + s1;
    }
    uint32_t a = h[0], b = h[1], c = h[2], d = h[3], e = h[4], f = h[5], g = h[6], hh = h[7];
    for (int i = 0; i < 64; ++i) {
      const uint32_t t1 = hh + (rotr(e, 6) ^ rotr(e, 11) ^ rotr(e, 25)) + ((e & f) ^ (~e & g)) + k[i] + w[i];
      const uint32_t t2 = (rotr(a, 2) ^ rotr(a, 13) ^ rotr(a, 22)) + ((a & b) ^ (a & c) ^ (b & c));
      hh = g, g = f, f = e, e = d + t1, d = c, c = b, b = a, a = t1 + t2;
    }
    h[0] += a, h[1] += b, h[2] += c, h[3] += d, h[4] += e, h[5] += f, h[6] += g, h[7] += hh;
  }
  char hex[65];
  for (int i = 0; i < 8; ++i) std::snprintf(hex + 8 * i, 9, "%08x", h[i]);
  return std::string(hex, 64);
}

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// "<recording>/<path inside it>" -> SHA-256 of every file of the recording.
void HashTree(const std::string& name, const fs::path& root, std::map<std::string, std::string>* sums) {
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.is_regular_file())
      (*sums)[name + "/" + fs::relative(e.path(), root).generic_string()] = Sha256(Slurp(e.path()));
}

// The recordings whose bytes are pinned: crowded enough that many rays and
// pixels end on people, short enough for a unit test.
std::map<std::string, SimOptions> PinnedRecordings() {
  std::map<std::string, SimOptions> r;
  SimOptions tiny = PresetOptions("tiny");
  tiny.seed = 4;
  tiny.crowdedness = 8;
  tiny.mapping_duration_s = 3;
  tiny.query_duration_s = 2;
  r["tiny"] = tiny;
  SimOptions small = PresetOptions("small");
  small.seed = 1;
  small.crowdedness = 5;
  small.mapping_duration_s = 1;
  small.query_duration_s = 1;
  r["small"] = small;
  // The large floor and crowd (306 people) with the large preset's 0.2 deg
  // LiDAR; small textures and images keep it fast.
  SimOptions large = PresetOptions("large");
  large.mapping_sequences = 1;
  large.validation_sequences = large.test_sequences = 0;
  large.mapping_duration_s = 1;
  large.texture_size = 64;
  large.rig.image_scale = 1.0 / 16;
  r["large"] = large;
  return r;
}

TEST(Sha256, KnownAnswers) {
  EXPECT_EQ(Sha256(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(Sha256("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(Sha256("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST(Recordings, EveryOutputByteMatchesThePinnedSums) {
  const fs::path fixture = LOCFORGE_SIM_TESTDATA "/recording_sha256.txt";
  std::map<std::string, std::string> sums;
  const fs::path dir = locforge::testing::MakeTempDir("sim_identity");
  for (const auto& [name, options] : PinnedRecordings()) {
    GenerateDataset(options, dir / name, 2);
    HashTree(name, dir / name, &sums);
  }
  std::ostringstream actual;  // sha256sum's format: `sha256sum -c` checks it inside `dir`
  for (const auto& [path, sum] : sums) actual << sum << "  " << path << "\n";
  if (const char* out = std::getenv("LOCFORGE_SIM_WRITE_SUMS")) {
    std::ofstream(out, std::ios::binary) << actual.str();
    std::printf("wrote %zu sums to %s\n", sums.size(), out);
  }

  std::map<std::string, std::string> expected;
  std::ifstream in(fixture);
  ASSERT_TRUE(in.good()) << "cannot read " << fixture;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    ASSERT_GT(line.size(), 66u) << fixture << ":" << n << ": expected '<sha256>  <path>'";
    expected[line.substr(66)] = line.substr(0, 64);
  }
  int differing = 0, missing = 0, extra = 0;
  for (const auto& [path, sum] : expected) {
    const auto it = sums.find(path);
    if (it == sums.end()) {
      if (++missing <= 5) ADD_FAILURE() << "not written: " << path;
    } else if (it->second != sum) {
      if (++differing <= 5) ADD_FAILURE() << "bytes differ: " << path;
    }
  }
  for (const auto& [path, sum] : sums)
    if (!expected.count(path) && ++extra <= 5) ADD_FAILURE() << "not in the fixture: " << path;
  std::printf("%zu files compared: %d differ, %d missing, %d extra\n", expected.size(), differing, missing, extra);
  EXPECT_GT(expected.size(), 500u);
  if (differing + missing + extra > 0) {
    ADD_FAILURE() << "outputs left in " << dir << "; if the change is intended, rerun with "
                  << "LOCFORGE_SIM_WRITE_SUMS=" << fixture.string() << " --gtest_filter=Recordings.*";
  } else {
    fs::remove_all(dir);
  }
}

}  // namespace
}  // namespace locforge::sim

// The strict ustar reader of tar-packed features: what Python's tarfile
// writes reads back, and every malformed or unsafe archive is refused with
// the archive and the entry named.
#include "locforge/kapture/tar.h"

#include <gtest/gtest.h>

#include <cstring>
#include <functional>

#include "locforge/error.h"
#include "locforge/kapture/kapture.h"
#include "testing.h"

namespace locforge::kapture {
namespace {

// One ustar header (as Python's tarfile writes it) and the data, padded.
std::string Entry(const std::string& name, const std::string& data, char type = '0',
                  const char* magic = "ustar\0" "00") {
  char h[512] = {};
  std::memcpy(h, name.data(), std::min<size_t>(name.size(), 100));
  std::snprintf(h + 100, 8, "%07o", 0644);
  std::snprintf(h + 108, 8, "%07o", 0);
  std::snprintf(h + 116, 8, "%07o", 0);
  std::snprintf(h + 124, 12, "%011o", static_cast<unsigned>(data.size()));
  std::snprintf(h + 136, 12, "%011o", 0);
  h[156] = type;
  std::memcpy(h + 257, magic, 8);
  std::memset(h + 148, ' ', 8);
  unsigned sum = 0;
  for (unsigned char c : h) sum += c;
  std::snprintf(h + 148, 8, "%06o", sum);
  std::string out(h, 512);
  out += data;
  out += std::string((512 - data.size() % 512) % 512, '\0');
  return out;
}

std::string End() { return std::string(1024, '\0'); }

fs::path Write(const fs::path& dir, const std::string& bytes) {
  const fs::path p = dir / "keypoints.tar";
  WriteFileAtomic(p, bytes);
  return p;
}

std::string ErrorOf(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

class Tar : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = locforge::testing::MakeTempDir("tar"); }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Refusal(const std::string& bytes) {
    const fs::path p = Write(dir_, bytes);
    return ErrorOf([&] { TarArchive archive(p, "keypoints.tar"); });
  }
  fs::path dir_;
};

TEST_F(Tar, IndexesFilesSkipsFoldersAndReadsEntries) {
  const fs::path p = Write(dir_, Entry("a.overlapping/", "", '5') + Entry("./a.jpg.kpt", "12345678") +
                                     Entry("a.overlapping/b.jpg.matches", std::string(600, 'x')) +
                                     End());
  const TarArchive archive(p, "keypoints.tar");
  ASSERT_EQ(archive.entries().size(), 2u);
  const TarEntry* e = archive.Find("a.jpg.kpt");
  ASSERT_TRUE(e);
  const std::vector<uint8_t> bytes = archive.Read(*e);
  EXPECT_EQ(std::string(bytes.begin(), bytes.end()), "12345678");
  EXPECT_EQ(archive.Find("a.overlapping/b.jpg.matches")->size, 600u);
  EXPECT_FALSE(archive.Find("a.overlapping"));
}

TEST_F(Tar, ANameStoredTwiceReadsAsItsLastCopy) {
  const fs::path p = Write(dir_, Entry("a.kpt", "old!") + Entry("a.kpt", "new!") + End());
  const TarArchive archive(p);
  const std::vector<uint8_t> bytes = archive.Read(*archive.Find("a.kpt"));
  EXPECT_EQ(std::string(bytes.begin(), bytes.end()), "new!");
}

TEST_F(Tar, ReadsPaxPathsAndGnuHeaders) {
  const std::string long_name = std::string(120, 'n') + ".kpt";
  const std::string record = "path=" + long_name + "\n";
  const std::string len = std::to_string(record.size() + 4);  // "NNN " + record
  const std::string pax = len + " " + record;
  ASSERT_EQ(pax.size(), std::stoul(len));
  const fs::path p = Write(dir_, Entry("PaxHeader", pax, 'x') + Entry("short", "abcd") +
                                     Entry("gnu.kpt", "xy", '0', "ustar  \0") + End());
  const TarArchive archive(p);
  EXPECT_TRUE(archive.Find(long_name));
  EXPECT_FALSE(archive.Find("short"));
  EXPECT_TRUE(archive.Find("gnu.kpt"));
}

TEST_F(Tar, RefusesNamesThatEscapeTheFolder) {
  for (const char* name : {"../up.kpt", "a/../../up.kpt", "/abs.kpt", "a//b.kpt", "a\\b.kpt"}) {
    const std::string why = Refusal(Entry(name, "1234") + End());
    EXPECT_NE(why.find("keypoints.tar: entry '"), std::string::npos) << name << ": " << why;
    EXPECT_NE(why.find(name), std::string::npos) << why;
  }
}

TEST_F(Tar, RefusesLinksDevicesAndFifos) {
  for (char type : {'1', '2', '3', '4', '6'}) {
    const std::string why = Refusal(Entry("a.kpt", "", type) + End());
    EXPECT_NE(why.find("entry 'a.kpt'"), std::string::npos) << why;
    EXPECT_NE(why.find("only regular files and folders"), std::string::npos) << why;
  }
}

TEST_F(Tar, RefusesDamagedArchives) {
  std::string bad_sum = Entry("a.kpt", "1234") + End();
  bad_sum[0] = 'b';  // the name changes, the checksum does not
  EXPECT_NE(Refusal(bad_sum).find("entry 'b.kpt' (header at byte 0): bad header checksum"),
            std::string::npos);
  std::string bad_magic = Entry("a.kpt", "1234", '0', "nottar\0") + End();
  EXPECT_NE(Refusal(bad_magic).find("bad magic"), std::string::npos);
  const std::string whole = Entry("a.kpt", std::string(1000, 'x')) + End();
  EXPECT_NE(Refusal(whole.substr(0, 900)).find("entry 'a.kpt' (header at byte 0): data runs past "
                                               "the end of the archive"),
            std::string::npos)
      << Refusal(whole.substr(0, 900));
  EXPECT_NE(Refusal(Entry("a.kpt", "1234")).find("no end-of-archive block"), std::string::npos);
  EXPECT_NE(Refusal(Entry("a.kpt", "1234") + std::string(100, '\0')).find("runs past the end"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { TarArchive a(dir_ / "absent.tar", "absent.tar"); }).find("absent.tar"),
            std::string::npos);
}

TEST_F(Tar, APackedTypeReadsInPlaceAndAWrongSizedEntryIsNamed) {
  const fs::path root = dir_ / "k";
  WriteFileAtomic(root / "sensors/sensors.txt", "cam, , camera, PINHOLE, 4, 4, 1, 1, 2, 2\n");
  const fs::path type_dir = root / "reconstruction/keypoints/t";
  WriteFileAtomic(type_dir / "keypoints.txt", "t, float32, 2\n");
  WriteFileAtomic(type_dir / "keypoints.tar",
                  Entry("a.jpg.kpt", std::string(16, '\1')) + Entry("b.jpg.kpt", "12345") + End());
  const Kapture k(root);
  EXPECT_EQ(k.FeatureImages(FeatureKind::kKeypoints, "t"),
            (std::vector<std::string>{"a.jpg", "b.jpg"}));
  EXPECT_EQ(k.ReadKeypoints("t", "a.jpg").rows, 2);
  const std::string why = ErrorOf([&] { k.ReadKeypoints("t", "b.jpg"); });
  EXPECT_NE(why.find("reconstruction/keypoints/t/keypoints.tar: entry 'b.jpg.kpt': size 5 bytes"),
            std::string::npos)
      << why;
  const std::string copy = ErrorOf([&] { CopyKapture(root, dir_ / "copy"); });
  EXPECT_NE(copy.find("keypoints.tar: entry 'b.jpg.kpt': size 5 bytes"), std::string::npos) << copy;
}

}  // namespace
}  // namespace locforge::kapture

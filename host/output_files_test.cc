// The output file list of a node folder: written, read back, and checked by
// size (every run) or by content (--verify).
#include "output_files.h"

#include <gtest/gtest.h>

#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/sha256.h"
#include "testing.h"

namespace locforge::host {
namespace {

class OutputFilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = locforge::testing::MakeTempDir("lf-output-files");
    WriteFileAtomic(dir_ / "a.txt", "alpha");
    WriteFileAtomic(dir_ / "sub/odd\tname\n.bin", std::string(300, 'b'));
    fs::create_symlink("a.txt", dir_ / "link.txt");
    WriteFileAtomic(dir_ / ".items-done.0-of-1", "x\n");  // bookkeeping: not listed
  }
  void TearDown() override { fs::remove_all(dir_); }
  // Publishes dir_ as a complete folder: list, then manifest.
  void Complete() {
    Manifest m;
    m.stage = "x/y";
    RecordOutputFiles(dir_, &m);
    WriteFileAtomic(dir_ / kCompleteMarker, FormatManifest(m));
  }
  fs::path dir_;
};

TEST_F(OutputFilesTest, ListRoundTripsWithOddNamesAndLinks) {
  const auto files = ListOutputFiles(dir_);
  ASSERT_EQ(files.size(), 3u);
  EXPECT_EQ(files[0].path, "a.txt");
  EXPECT_EQ(files[0].size, 5u);
  EXPECT_EQ(files[0].sha256, Sha256Hex("alpha"));
  EXPECT_EQ(files[1].path, "link.txt");
  EXPECT_TRUE(files[1].link);
  EXPECT_EQ(files[2].path, "sub/odd\tname\n.bin");
  const auto back = ParseFileList(FormatFileList(files), "list");
  ASSERT_EQ(back.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(back[i].path, files[i].path);
    EXPECT_EQ(back[i].link, files[i].link);
    EXPECT_EQ(back[i].size, files[i].size);
    EXPECT_EQ(back[i].sha256, files[i].sha256);
  }
  try {
    ParseFileList("# header\nf\t12\tnothex\ta.txt\n", "L");
    FAIL() << "a bad hash accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("L:2: field 'sha256'"), std::string::npos) << e.what();
  }
}

TEST_F(OutputFilesTest, SizesEveryRunContentsOnlyWhenHashed) {
  Complete();
  EXPECT_TRUE(CheckNodeFolder(dir_, false).ok());
  FolderCheck full = CheckNodeFolder(dir_, true);
  EXPECT_TRUE(full.ok()) << DamageText(full);
  EXPECT_EQ(full.files, 3u);
  EXPECT_EQ(full.bytes_hashed, 305u);
  WriteFileAtomic(dir_ / "a.txt", "ALPHA");  // same size
  EXPECT_TRUE(CheckNodeFolder(dir_, false).ok());
  full = CheckNodeFolder(dir_, true);
  ASSERT_EQ(full.damage.size(), 1u);
  EXPECT_EQ(full.damage[0].rfind("a.txt: content changed", 0), 0u) << full.damage[0];
  WriteFileAtomic(dir_ / "a.txt", "alph");
  fs::remove(dir_ / "link.txt");
  const FolderCheck quick = CheckNodeFolder(dir_, false);
  ASSERT_EQ(quick.damage.size(), 2u);
  EXPECT_EQ(quick.damage[0], "a.txt: size 4 bytes, recorded 5");
  EXPECT_EQ(quick.damage[1], "link.txt: missing");
}

TEST_F(OutputFilesTest, AnEditedListOrAnOldManifest) {
  Complete();
  const std::string extra = "f\t1\t" + std::string(64, '0') + "\tz\n";
  WriteFileAtomic(dir_ / kFileList, ReadFile(dir_ / kFileList) + extra);
  const FolderCheck edited = CheckNodeFolder(dir_, false);
  ASSERT_EQ(edited.damage.size(), 1u);
  EXPECT_NE(edited.damage[0].find("differs from the manifest's"), std::string::npos);
  WriteFileAtomic(dir_ / kCompleteMarker, "{\"stage\": \"x/y\"}\n");  // before file lists
  const FolderCheck old = CheckNodeFolder(dir_, true);
  EXPECT_FALSE(old.verifiable);
  EXPECT_TRUE(old.ok());
  WriteFileAtomic(dir_ / kCompleteMarker, "{\"stage\": [\n");  // torn: damage, not a crash
  EXPECT_FALSE(CheckNodeFolder(dir_, false).ok());
}

}  // namespace
}  // namespace locforge::host

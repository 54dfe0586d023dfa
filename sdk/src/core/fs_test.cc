#include "locforge/fs.h"

#include <gtest/gtest.h>

#include <stdexcept>

#include "locforge/error.h"
#include "testing.h"

namespace locforge {
namespace {

class FsTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = locforge::testing::MakeTempDir("locforge-fs-test"); }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  // Names in `folder`, sorted.
  std::vector<std::string> Listing(const fs::path& folder) const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(folder)) names.push_back(e.path().filename());
    std::sort(names.begin(), names.end());
    return names;
  }
  fs::path dir_;
};

TEST_F(FsTest, WriteFileAtomicLeavesNoTempFile) {
  const fs::path target = dir_ / "sub" / "deeper" / "result.txt";
  WriteFileAtomic(target, "hello\n");
  EXPECT_EQ(ReadFile(target), "hello\n");
  EXPECT_EQ(Listing(target.parent_path()), std::vector<std::string>{"result.txt"});
  // Overwrite, binary content with NULs.
  const std::string binary("a\0b\0c", 5);
  WriteFileAtomic(target, binary);
  EXPECT_EQ(ReadFile(target), binary);
  EXPECT_EQ(Listing(target.parent_path()), std::vector<std::string>{"result.txt"});
  WriteFileAtomic(target, "");
  EXPECT_EQ(ReadFile(target), "");
}

TEST_F(FsTest, LinkOrCopyFilePublishesAWholeFileAndCleansUpOnFailure) {
  const fs::path source = dir_ / "a" / "image.jpg";
  WriteFileAtomic(source, "pixels");
  const fs::path target = dir_ / "b" / "c" / "image.jpg";
  LinkOrCopyFile(source, target);
  EXPECT_EQ(ReadFile(target), "pixels");
  EXPECT_EQ(fs::hard_link_count(target), 2u);  // same file system: a link, not a copy
  EXPECT_EQ(Listing(target.parent_path()), std::vector<std::string>{"image.jpg"});
  // A missing source: an error naming both paths, nothing left beside the target.
  try {
    LinkOrCopyFile(dir_ / "a" / "missing.jpg", dir_ / "b" / "c" / "other.jpg");
    ADD_FAILURE() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.jpg"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("other.jpg"), std::string::npos) << e.what();
  }
  EXPECT_EQ(Listing(target.parent_path()), std::vector<std::string>{"image.jpg"});
}

TEST_F(FsTest, AtomicFileWithoutCommitKeepsOldContent) {
  const fs::path target = dir_ / "model.txt";
  WriteFileAtomic(target, "old content");
  {
    AtomicFile f(target);
    f.stream() << "half-written new content";
    f.stream().flush();
    // While writing, readers still see the old file.
    EXPECT_EQ(ReadFile(target), "old content");
  }  // destroyed without Commit
  EXPECT_EQ(ReadFile(target), "old content");
  EXPECT_EQ(Listing(dir_), std::vector<std::string>{"model.txt"});
}

TEST_F(FsTest, AtomicFileUnwoundByExceptionKeepsOldContent) {
  const fs::path target = dir_ / "model.txt";
  WriteFileAtomic(target, "old");
  EXPECT_THROW(
      {
        AtomicFile f(target);
        f.stream() << "new";
        throw std::runtime_error("stage failed midway");
      },
      std::runtime_error);
  EXPECT_EQ(ReadFile(target), "old");
  EXPECT_EQ(Listing(dir_), std::vector<std::string>{"model.txt"});
}

TEST_F(FsTest, AtomicFileWithoutCommitCreatesNothing) {
  { AtomicFile f(dir_ / "never.txt"); f.stream() << "x"; }
  EXPECT_TRUE(Listing(dir_).empty());
}

TEST_F(FsTest, AtomicFileCommit) {
  const fs::path target = dir_ / "out.bin";
  AtomicFile f(target);
  EXPECT_EQ(f.path(), target);
  f.stream() << "line 1\n" << 42 << "\n";
  EXPECT_FALSE(fs::exists(target));
  f.Commit();
  EXPECT_EQ(ReadFile(target), "line 1\n42\n");
  f.Commit();  // a second Commit is harmless
  EXPECT_EQ(ReadFile(target), "line 1\n42\n");
  EXPECT_EQ(Listing(dir_), std::vector<std::string>{"out.bin"});
}

TEST_F(FsTest, TempSiblingIsBesideAndUnique) {
  const fs::path target = dir_ / "a.txt";
  const fs::path t1 = TempSibling(target), t2 = TempSibling(target);
  EXPECT_EQ(t1.parent_path(), dir_);
  EXPECT_NE(t1, t2);
  EXPECT_NE(t1.filename().string().find("a.txt"), std::string::npos);
}

TEST_F(FsTest, ReadFileMissingNamesTheFile) {
  try {
    ReadFile(dir_ / "missing.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.code(), LF_BAD_INPUT);
    EXPECT_NE(std::string(e.what()).find("missing.txt"), std::string::npos) << e.what();
  }
}

TEST_F(FsTest, SafeJoinAcceptsNestedPaths) {
  const fs::path root = dir_ / "dataset";
  fs::create_directories(root / "sensors" / "records_data" / "cam0");
  WriteFileAtomic(root / "sensors" / "records_data" / "cam0" / "0001.jpg", "jpg");
  EXPECT_EQ(SafeJoin(root, "sensors/records_data/cam0/0001.jpg"),
            root / "sensors" / "records_data" / "cam0" / "0001.jpg");
  // Paths that do not exist yet (outputs) are fine.
  EXPECT_EQ(SafeJoin(root, "new/folder/file.txt"), root / "new" / "folder" / "file.txt");
  // "." and ".." that stay inside are normalised away.
  EXPECT_EQ(SafeJoin(root, "./sensors/../sensors/records_data"),
            root / "sensors" / "records_data");
  // A symlink that stays inside the root is followed happily.
  fs::create_directory_symlink(root / "sensors" / "records_data", root / "data_link");
  EXPECT_EQ(SafeJoin(root, "data_link/cam0/0001.jpg"), root / "data_link" / "cam0" / "0001.jpg");
  // The root itself reached through a symlink.
  fs::create_directory_symlink(root, dir_ / "root_link");
  EXPECT_EQ(SafeJoin(dir_ / "root_link", "sensors/records_data/cam0/0001.jpg"),
            dir_ / "root_link" / "sensors" / "records_data" / "cam0" / "0001.jpg");
}

template <typename F>
void ExpectRefused(F&& f, const std::vector<std::string>& fragments) {
  try {
    f();
    ADD_FAILURE() << "path accepted";
  } catch (const InputError& e) {
    for (const auto& fragment : fragments)
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos)
          << "'" << fragment << "' not in: " << e.what();
  }
}

TEST_F(FsTest, SafeJoinRefusesEscapes) {
  const fs::path root = dir_ / "dataset";
  fs::create_directories(root / "a");
  const std::string origin = "records_camera.txt:12";
  ExpectRefused([&] { SafeJoin(root, "../secret", origin); },
                {"records_camera.txt:12", "'../secret'", "escapes"});
  ExpectRefused([&] { SafeJoin(root, "a/../../secret", origin); }, {"escapes"});
  ExpectRefused([&] { SafeJoin(root, "a/b/../../../secret", origin); }, {"escapes"});
  ExpectRefused([&] { SafeJoin(root, "/etc/passwd", origin); }, {"absolute"});
  ExpectRefused([&] { SafeJoin(root, "", origin); }, {"empty"});
  // Without an origin the message names the root.
  ExpectRefused([&] { SafeJoin(root, "../x"); }, {root.string()});
}

TEST_F(FsTest, SafeJoinRefusesSymlinkOutside) {
  const fs::path root = dir_ / "dataset";
  const fs::path outside = dir_ / "outside";
  fs::create_directories(root);
  fs::create_directories(outside);
  WriteFileAtomic(outside / "secret.txt", "secret");
  fs::create_directory_symlink(outside, root / "link");
  ExpectRefused([&] { SafeJoin(root, "link/secret.txt", "trajectories.txt:3"); },
                {"trajectories.txt:3", "symbolic link"});
  ExpectRefused([&] { SafeJoin(root, "link"); }, {"outside"});
  // A file symlink too, and one whose target does not exist yet.
  fs::create_symlink(outside / "secret.txt", root / "file_link");
  ExpectRefused([&] { SafeJoin(root, "file_link"); }, {"outside"});
  fs::create_symlink(outside / "not_yet.txt", root / "dangling");
  ExpectRefused([&] { SafeJoin(root, "dangling"); }, {"outside"});
  // A relative link climbing out.
  fs::create_directory_symlink("../outside", root / "relative_link");
  ExpectRefused([&] { SafeJoin(root, "relative_link/secret.txt"); }, {"outside"});
  // A sibling whose name starts like the root is still outside.
  fs::create_directories(dir_ / "dataset2");
  fs::create_directory_symlink(dir_ / "dataset2", root / "sibling");
  ExpectRefused([&] { SafeJoin(root, "sibling/x"); }, {"outside"});
}

TEST_F(FsTest, SafeJoinRefusesSymlinkLoop) {
  const fs::path root = dir_ / "dataset";
  fs::create_directories(root);
  fs::create_symlink("loop", root / "loop");
  EXPECT_THROW(SafeJoin(root, "loop/file"), InputError);
}

}  // namespace
}  // namespace locforge

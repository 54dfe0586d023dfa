// `locforge colmap ...` as a user runs it: exit codes, outputs, messages.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "locforge/colmap/database.h"
#include "locforge/colmap/model.h"
#include "locforge/colmap/run.h"
#include "locforge/fs.h"
#include "testing.h"

namespace {

namespace fs = std::filesystem;
using namespace locforge;

struct Result {
  int code = -1;
  std::string output;  // stdout + stderr
};

std::string Quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// Test-only: the test drives the binary through the shell like a user would.
Result Locforge(const std::vector<std::string>& args) {
  const char* bin = std::getenv("LOCFORGE_BIN");
  std::string cmd = Quote(bin ? bin : "locforge");
  for (const std::string& a : args) cmd += " " + Quote(a);
  cmd += " 2>&1";
  Result r;
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0) r.output.append(buf.data(), n);
  const int status = ::pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

class ColmapCli : public ::testing::Test {
 protected:
  void SetUp() override { tmp_ = locforge::testing::MakeTempDir("colmap_cli"); }
  void TearDown() override { fs::remove_all(tmp_); }
  fs::path tmp_;
};

TEST_F(ColmapCli, HelpAndUsageErrors) {
  Result r = Locforge({"colmap", "--help"});
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("locforge colmap export KAPTURE_DIR --database DB"), std::string::npos);
  EXPECT_NE(r.output.find("locforge colmap import --database DB"), std::string::npos);
  EXPECT_EQ(Locforge({"colmap"}).code, 2);
  EXPECT_EQ(Locforge({"colmap", "frobnicate"}).code, 2);
  r = Locforge({"colmap", "export", tmp_.string()});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("--database"), std::string::npos) << r.output;
  EXPECT_EQ(Locforge({"colmap", "export", tmp_.string(), "--database"}).code, 2);
  EXPECT_EQ(Locforge({"colmap", "export", tmp_.string(), "--database", "x.db", "--bogus"}).code, 2);
  EXPECT_EQ(Locforge({"colmap", "import", (tmp_ / "out").string()}).code, 2);
  r = Locforge({"colmap", "export", (tmp_ / "absent").string(), "--database", "x.db"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("is not a folder"), std::string::npos) << r.output;
}

TEST_F(ColmapCli, ExportAndImportMaupertuis) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, "data/kapture/maupertuis");
  Result r = Locforge({"colmap", "export", (root / "kapture").string(), "--database",
                       (tmp_ / "db.db").string(), "--model", (tmp_ / "model").string(),
                       "--binary"});
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("1 cameras, 4 images (4 posed)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1039 points3D (3355 observations"), std::string::npos) << r.output;
  EXPECT_EQ(colmap::ReadModelBinary(tmp_ / "model").points3d.size(), 1039u);
  EXPECT_EQ(colmap::Database(tmp_ / "db.db").NumMatchedPairs(), 6u);
  // Existing database: refused (work failed), then allowed with --overwrite.
  r = Locforge({"colmap", "export", (root / "kapture").string(), "--database",
                (tmp_ / "db.db").string()});
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("exists"), std::string::npos) << r.output;
  EXPECT_EQ(Locforge({"colmap", "export", (root / "kapture").string(), "--database",
                      (tmp_ / "db.db").string(), "--overwrite", "--no-points"})
                .code,
            0);

  r = Locforge({"colmap", "import", "--database", (root / "colmap/colmap.db").string(), "--model",
                (root / "colmap/reconstruction").string(), (tmp_ / "kapture").string()});
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("1039 points3d (3355 observations)"), std::string::npos) << r.output;
  EXPECT_EQ(ReadFile(tmp_ / "kapture/sensors/records_camera.txt"),
            ReadFile(root / "kapture/sensors/records_camera.txt"));
  EXPECT_EQ(ReadFile(tmp_ / "kapture/reconstruction/keypoints/SIFT/02.jpg.kpt"),
            ReadFile(root / "kapture/reconstruction/keypoints/SIFT/02.jpg.kpt"));
  EXPECT_EQ(ReadFile(tmp_ / "kapture/reconstruction/observations.txt"),
            ReadFile(root / "kapture/reconstruction/observations.txt"));
}

TEST_F(ColmapCli, BadInputExitsTwoNamingTheFile) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, "data/kapture/maupertuis");
  fs::create_directories(tmp_ / "model");
  for (const char* f : {"cameras.txt", "images.txt", "points3D.txt"}) {
    fs::copy_file(root / "colmap/reconstruction" / f, tmp_ / "model" / f);
  }
  std::string images = ReadFile(tmp_ / "model/images.txt");
  images.replace(images.find("0.860298"), 8, "0.86x298");
  WriteFileAtomic(tmp_ / "model/images.txt", images);
  const Result r = Locforge({"colmap", "import", "--model", (tmp_ / "model").string(),
                             (tmp_ / "kapture").string()});
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("images.txt:5: field 'QW'"), std::string::npos) << r.output;
}

}  // namespace

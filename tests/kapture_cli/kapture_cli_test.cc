// `locforge kapture` through the real executable ($LOCFORGE_BIN): output,
// exit codes (0 ok, 1 failed / --strict problems, 2 bad usage or input).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include "locforge/fs.h"
#include "testing.h"

namespace {

namespace fs = std::filesystem;

struct Result {
  int code = -1;
  std::string output;  // stdout and stderr
};

std::string Quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

Result RunKapture(const std::string& args) {
  const char* bin = std::getenv("LOCFORGE_BIN");
  Result r;
  if (!bin) {
    r.output = "LOCFORGE_BIN is not set";
    return r;
  }
  const std::string cmd = Quote(bin) + " kapture " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof(buf), p)) > 0) r.output.append(buf, n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

bool Has(const Result& r, const std::string& piece) {
  return r.output.find(piece) != std::string::npos;
}

TEST(KaptureCli, Help) {
  const Result r = RunKapture("--help");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(Has(r, "Usage: locforge kapture info DIR")) << r.output;
  EXPECT_TRUE(Has(r, "locforge kapture copy SRC DST")) << r.output;
  EXPECT_EQ(RunKapture("").code, 2);
  EXPECT_EQ(RunKapture("frobnicate").code, 2);
  EXPECT_EQ(RunKapture("info").code, 2);
  EXPECT_EQ(RunKapture("info --bogus x").code, 2);
  EXPECT_EQ(RunKapture("copy onlyone").code, 2);
}

TEST(KaptureCli, InfoM1x) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, "data/kapture/m1x_metadata");
  const Result r = RunKapture(Quote(dir.string()));
  EXPECT_EQ(r.code, 2) << "no subcommand: " << r.output;
  const Result info = RunKapture("info " + Quote(dir.string()));
  ASSERT_EQ(info.code, 0) << info.output;
  EXPECT_TRUE(Has(info, "sensors: 14 (bluetooth 1, camera 10, lidar 2, wifi 1)")) << info.output;
  EXPECT_TRUE(Has(info, "rigs: 1 (14 sensor entries)")) << info.output;
  EXPECT_TRUE(Has(info, "trajectories: 9 poses, 1 devices")) << info.output;
  EXPECT_TRUE(Has(info, "records lidar: 6 from 2 devices")) << info.output;
  EXPECT_TRUE(Has(info, "records wifi: 6 from 2 devices")) << info.output;
  EXPECT_TRUE(Has(info, "records bluetooth: 6 from 2 devices")) << info.output;
  EXPECT_TRUE(Has(info, "keypoints SIFT: SIFT, float x 4, 0 files")) << info.output;
  // The public metadata ships no images, no scans and one device per kind.
  EXPECT_TRUE(Has(info, "records camera: 18 from 9 devices")) << info.output;
  EXPECT_TRUE(Has(info, "18 files missing")) << info.output;
  EXPECT_TRUE(Has(info, "device 'AC01324955_wifi' is not in sensors.txt")) << info.output;
  EXPECT_EQ(RunKapture("info --strict " + Quote(dir.string())).code, 1);
}

TEST(KaptureCli, InfoMaupertuisIsClean) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, "data/kapture/maupertuis/kapture");
  const Result info = RunKapture("info --strict " + Quote(dir.string()));
  EXPECT_EQ(info.code, 0) << info.output;
  EXPECT_TRUE(Has(info, "keypoints SIFT: SIFT, float32 x 6, 4 files")) << info.output;
  EXPECT_TRUE(Has(info, "descriptors SIFT: SIFT, uint8 x 128, 4 files")) << info.output;
  EXPECT_TRUE(Has(info, "matches SIFT: 6 image pairs")) << info.output;
  EXPECT_TRUE(Has(info, "reconstruction: 1039 points3d")) << info.output;
  EXPECT_TRUE(Has(info, "problems: none")) << info.output;
}

TEST(KaptureCli, InfoBadInputs) {
  EXPECT_EQ(RunKapture("info /nonexistent/kapture").code, 2);
  const fs::path tmp = locforge::testing::MakeTempDir("kapture_cli_bad");
  EXPECT_EQ(RunKapture("info " + Quote(tmp.string())).code, 2);  // not a kapture
  locforge::WriteFileAtomic(tmp / "sensors/sensors.txt", "cam, , camera, PINHOLE, 640, 480, 5, 5, 3, 3\n");
  locforge::WriteFileAtomic(tmp / "sensors/records_camera.txt",
                            "# kapture format: 1.1\n1, cam, ../../etc/passwd\n");
  const Result r = RunKapture("info " + Quote(tmp.string()));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_TRUE(Has(r, "sensors/records_camera.txt:2: field 'path'")) << r.output;
  EXPECT_TRUE(Has(r, "escapes")) << r.output;
  locforge::WriteFileAtomic(tmp / "sensors/records_camera.txt", "1, cam, a.jpg\n");
  locforge::WriteFileAtomic(tmp / "sensors/trajectories.txt", "1, cam, 1, 0, 0, 0, 0, 0, abc\n");
  const Result t = RunKapture("info " + Quote(tmp.string()));
  EXPECT_EQ(t.code, 2);
  EXPECT_TRUE(Has(t, "sensors/trajectories.txt:1: field 'tz': expected a number, got 'abc'"))
      << t.output;
  fs::remove_all(tmp);
}

TEST(KaptureCli, Copy) {
  LOCFORGE_SHARED_PATH_OR_SKIP(src, "data/kapture/maupertuis/kapture");
  const fs::path tmp = locforge::testing::MakeTempDir("kapture_cli_copy");
  const fs::path dst = tmp / "out";
  const Result r = RunKapture("copy " + Quote(src.string()) + " " + Quote(dst.string()));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(Has(r, "14 feature/matches files, 4 record data files")) << r.output;
  for (const char* rel : {"reconstruction/keypoints/SIFT/00.jpg.kpt",
                          "reconstruction/matches/SIFT/00.jpg.overlapping/01.jpg.matches",
                          "sensors/records_data/02.jpg"})
    EXPECT_TRUE(locforge::ReadFile(src / rel) == locforge::ReadFile(dst / rel)) << rel;
  const Result again = RunKapture("copy " + Quote(src.string()) + " " + Quote(dst.string()));
  EXPECT_EQ(again.code, 2);
  EXPECT_TRUE(Has(again, "not empty")) << again.output;
  EXPECT_EQ(RunKapture("copy --overwrite " + Quote(src.string()) + " " + Quote(dst.string())).code, 0);
  const Result into = RunKapture("copy " + Quote(dst.string()) + " " + Quote((dst / "sub").string()));
  EXPECT_EQ(into.code, 2);
  EXPECT_TRUE(Has(into, "refusing")) << into.output;
  // The copy reads back with the same summary.
  const Result a = RunKapture("info " + Quote(src.string())), b = RunKapture("info " + Quote(dst.string()));
  EXPECT_EQ(a.output.substr(a.output.find('\n')), b.output.substr(b.output.find('\n')));
  fs::remove_all(tmp);
}

}  // namespace

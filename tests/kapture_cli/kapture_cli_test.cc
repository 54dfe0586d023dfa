// `locforge kapture` through the real executable ($LOCFORGE_BIN): output,
// exit codes (0 ok, 1 failed / --strict problems, 2 bad usage or input).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

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
  EXPECT_TRUE(Has(r, "locforge kapture export W OUT")) << r.output;
  EXPECT_EQ(RunKapture("export onlyone").code, 2);
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

// `kapture export` of a workspace whose nodes each hold a part of maupertuis
// (as a dataset, features, matches and mapper node do): one kapture equal to
// the sample, records linked; unfinished or unknown nodes refused.
TEST(KaptureCli, ExportJoinsNodeParts) {
  LOCFORGE_SHARED_PATH_OR_SKIP(src, "data/kapture/maupertuis/kapture");
  const fs::path tmp = locforge::testing::MakeTempDir("kapture_cli_export");
  const fs::path ws = tmp / "ws", out = tmp / "out";
  const std::pair<const char*, std::vector<const char*>> parts[] = {
      {"dataset", {"sensors"}},
      {"features", {"reconstruction/keypoints", "reconstruction/descriptors"}},
      {"matches", {"reconstruction/matches"}},
      {"mapper", {"reconstruction/points3d.txt", "reconstruction/observations.txt"}}};
  for (const auto& [node, paths] : parts) {
    for (const char* rel : paths) {
      fs::create_directories((ws / "nodes" / node / rel).parent_path());
      fs::copy(src / rel, ws / "nodes" / node / rel, fs::copy_options::recursive);
    }
    if (std::string(node) != "mapper") locforge::WriteFileAtomic(ws / "nodes" / node / ".locforge-complete", "{}");
  }
  const std::string nodes = " --nodes dataset,features,matches,mapper";
  Result r = RunKapture("export " + Quote(ws.string()) + " " + Quote(out.string()) + nodes);
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(Has(r, "node 'mapper' has not finished")) << r.output;
  locforge::WriteFileAtomic(ws / "nodes/mapper/.locforge-complete", "{}");
  r = RunKapture("export " + Quote(ws.string()) + " " + Quote(out.string()) + nodes);
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(Has(r, ", 4 camera records")) << r.output;
  EXPECT_TRUE(Has(r, ", 4 record files, 4 descriptors/SIFT files, 4 keypoints/SIFT files, 6 SIFT match pairs, "
                     "1039 points3d")) << r.output;
  const Result info = RunKapture("info --strict " + Quote(out.string()));
  EXPECT_EQ(info.code, 0) << info.output;
  EXPECT_TRUE(Has(info, "problems: none")) << info.output;
  for (const char* rel : {"reconstruction/keypoints/SIFT/00.jpg.kpt", "reconstruction/descriptors/SIFT/03.jpg.desc",
                          "reconstruction/matches/SIFT/00.jpg.overlapping/01.jpg.matches", "sensors/records_data/02.jpg"})
    EXPECT_TRUE(locforge::ReadFile(src / rel) == locforge::ReadFile(out / rel)) << rel;
  EXPECT_TRUE(fs::is_symlink(out / "sensors/records_data/02.jpg"));
  EXPECT_EQ(RunKapture("export " + Quote(ws.string()) + " " + Quote(out.string()) + nodes).code, 2);  // not empty
  r = RunKapture("export " + Quote(ws.string()) + " " + Quote((tmp / "o2").string()) + " --nodes dataset,nothere");
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(Has(r, "no node 'nothere'")) << r.output;
  r = RunKapture("export " + Quote(ws.string()) + " " + Quote((tmp / "o3").string()));
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(Has(r, "no run record")) << r.output;
  EXPECT_EQ(RunKapture("export " + Quote(src.string()) + " " + Quote((tmp / "o4").string())).code, 2);
  EXPECT_FALSE(fs::exists(tmp / "o2"));
  fs::remove_all(tmp);
}

// The kapture toolbox's own samples (../shared/data/kapture/toolbox_samples):
// each reads; all but t265, which ships no images, are clean under --strict.
TEST(KaptureCli, InfoToolboxSamples) {
  LOCFORGE_SHARED_PATH_OR_SKIP(samples, "data/kapture/toolbox_samples");
  for (const char* name : {"berlin", "berlin_tar", "cour_carree_markers", "maupertuis_openmvg",
                           "t265", "utbm"}) {
    SCOPED_TRACE(name);
    const std::string dir = Quote((samples / name).string());
    const Result info = RunKapture("info " + dir);
    EXPECT_EQ(info.code, 0) << info.output;
    const Result strict = RunKapture("info --strict " + dir);
    if (std::string(name) == "t265") {
      EXPECT_EQ(strict.code, 1) << strict.output;
      EXPECT_TRUE(Has(strict, "records camera: 6 from 2 devices")) << strict.output;
      EXPECT_TRUE(Has(strict, "6 files missing")) << strict.output;
    } else {
      EXPECT_EQ(strict.code, 0) << strict.output;
      EXPECT_TRUE(Has(strict, "problems: none")) << strict.output;
    }
  }
  // The tar-packed berlin counts the same features as the loose one.
  const Result loose = RunKapture("info " + Quote((samples / "berlin").string()));
  const Result packed = RunKapture("info " + Quote((samples / "berlin_tar").string()));
  EXPECT_EQ(loose.output.substr(loose.output.find('\n')),
            packed.output.substr(packed.output.find('\n')));
  EXPECT_TRUE(Has(packed, "keypoints HessianAffine: HessianAffine, float32 x 4, 3 files"))
      << packed.output;
  EXPECT_TRUE(Has(packed, "matches HessianAffine: 3 image pairs")) << packed.output;
  const Result openmvg = RunKapture("info " + Quote((samples / "maupertuis_openmvg").string()));
  EXPECT_TRUE(Has(openmvg, "reconstruction: ")) << openmvg.output;
  EXPECT_FALSE(Has(openmvg, "reconstruction: 0 points3d")) << openmvg.output;
}

TEST(KaptureCli, CopyKeepsTarPackedFeaturesUnpacksOnRequestAndRefusesADamagedArchive) {
  LOCFORGE_SHARED_PATH_OR_SKIP(src, "data/kapture/toolbox_samples/berlin_tar");
  const fs::path tmp = locforge::testing::MakeTempDir("kapture_cli_tar");
  const fs::path dst = tmp / "out";
  const Result r = RunKapture("copy " + Quote(src.string()) + " " + Quote(dst.string()));
  ASSERT_EQ(r.code, 0) << r.output;
  const std::string kpt = "reconstruction/keypoints/HessianAffine/keypoints.tar";
  for (const std::string rel : {kpt, std::string("reconstruction/descriptors/HOG/descriptors.tar"),
                                std::string("reconstruction/matches/HessianAffine/matches.tar")})
    EXPECT_TRUE(locforge::ReadFile(src / rel) == locforge::ReadFile(dst / rel)) << rel;
  // --unpack: the files written loose, as the unpacked sample holds them.
  LOCFORGE_SHARED_PATH_OR_SKIP(loose, "data/kapture/toolbox_samples/berlin");
  const fs::path unpacked = tmp / "unpacked";
  const Result u = RunKapture("copy --unpack " + Quote(src.string()) + " " + Quote(unpacked.string()));
  ASSERT_EQ(u.code, 0) << u.output;
  EXPECT_TRUE(Has(u, "9 feature/matches files")) << u.output;
  int64_t loose_files = 0;
  for (const auto& e : fs::recursive_directory_iterator(loose / "reconstruction")) {
    if (!e.is_regular_file() || e.path().extension() == ".txt") continue;
    ++loose_files;
    const std::string rel = e.path().lexically_relative(loose).generic_string();
    EXPECT_TRUE(locforge::ReadFile(e.path()) == locforge::ReadFile(unpacked / rel)) << rel;
  }
  EXPECT_EQ(loose_files, 9);
  EXPECT_FALSE(fs::exists(unpacked / kpt));
  const Result a = RunKapture("info " + Quote(loose.string()));
  const Result b = RunKapture("info " + Quote(unpacked.string()));
  EXPECT_EQ(a.output.substr(a.output.find('\n')), b.output.substr(b.output.find('\n')));
  // Another mtime digit in the first entry's header: its checksum no longer holds.
  std::string bytes = locforge::ReadFile(dst / kpt);
  bytes[140] = bytes[140] == '0' ? '1' : '0';
  fs::permissions(dst / kpt, fs::perms::owner_write, fs::perm_options::add);
  locforge::WriteFileAtomic(dst / kpt, bytes);
  const Result bad = RunKapture("info " + Quote(dst.string()));
  EXPECT_EQ(bad.code, 2) << bad.output;
  EXPECT_TRUE(Has(bad, kpt + ": entry '01.jpg.kpt' (header at byte 0)")) << bad.output;
  EXPECT_TRUE(Has(bad, "bad header checksum")) << bad.output;
  fs::remove_all(tmp);
}

}  // namespace

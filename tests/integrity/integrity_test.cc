// A damaged image through the host: the query kapture of
// virtual_gallery_tutorial (4 real JPEGs) copied with one image truncated to
// 30 kB. features/sift must fail that item, and only it, and say so in the
// node's failures.txt, the run's error and the report; `kapture info
// --check-images` must list it. Before, libjpeg only printed "Premature end
// of JPEG file", SIFT ran on the half-grey image and the run exited 0.
#include <gtest/gtest.h>

#include <fstream>
#include <set>

#include "locforge/fs.h"
#include "testing.h"

namespace locforge {
namespace {

constexpr char kBad[] = "testing/gallery_light1_occlusion1/frames/rgb/camera_0/rgb_00446.jpg";

bool Has(const std::string& text, const std::string& piece) {
  return text.find(piece) != std::string::npos;
}

// A writable copy of the query kapture with kBad cut to 30 kB.
fs::path DamagedCopy(const fs::path& source, const fs::path& dir) {
  const fs::path copy = dir / "query";
  // File by file: shared/ is read-only and its modes would be copied with it.
  for (const auto& e : fs::recursive_directory_iterator(source)) {
    const fs::path to = copy / e.path().lexically_relative(source);
    fs::create_directories(e.is_directory() ? to : to.parent_path());
    if (e.is_regular_file()) {
      fs::copy_file(e.path(), to);
      fs::permissions(to, fs::perms::owner_write, fs::perm_options::add);
    }
  }
  fs::resize_file(copy / "sensors/records_data" / kBad, 30000);
  return copy;
}

// Names of the files under `dir` ending in `suffix`.
std::set<std::string> FilesEndingIn(const fs::path& dir, const std::string& suffix) {
  std::set<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name.size() >= suffix.size() && name.substr(name.size() - suffix.size()) == suffix)
      out.insert(name);
  }
  return out;
}

TEST(Integrity, TruncatedQueryImageFailsItsItemAndIsNamedEverywhere) {
  LOCFORGE_SHARED_PATH_OR_SKIP(source, "data/kapture/virtual_gallery_tutorial/query");
  const fs::path bin = LOCFORGE_BINARY_DIR;
  const fs::path dir = testing::MakeTempDir("lf-integrity");
  const fs::path copy = DamagedCopy(source, dir);
  std::ofstream(dir / "sift.yaml") << "locforge: 1\nnodes:\n"
                                   << "  query:\n    stage: source/kapture_folder\n"
                                   << "    params: {path: \"" << copy.string() << "\"}\n"
                                   << "  sift:\n    stage: features/sift\n"
                                   << "    inputs: {images: query.dataset}\n"
                                   << "    params: {max_keypoints: 500}\n";
  const fs::path ws = dir / "ws";
  ASSERT_EQ(testing::RunHost(bin, {"run", (dir / "sift.yaml").string(), "--workspace", ws.string(),
                                   "--threads", "2"},
                             dir / "run.log"),
            1)
      << testing::ReadText(dir / "run.log");
  const std::string log = testing::ReadText(dir / "run.log");
  EXPECT_TRUE(Has(log, "1 of 4 items failed: item '" + std::string(kBad) + "'")) << log;
  EXPECT_TRUE(Has(log, "truncated JPEG (libjpeg: Premature end of JPEG file)")) << log;

  // The partial folder: the other three images described and journaled, the
  // damaged one listed in failures.txt with the reason.
  fs::path partial;
  for (const auto& e : fs::directory_iterator(ws / "cache"))
    if (e.path().filename().string().rfind("sift-", 0) == 0) partial = e.path();
  ASSERT_TRUE(Has(partial.filename().string(), ".partial")) << partial;
  EXPECT_EQ(FilesEndingIn(partial, ".jpg.kpt"),
            (std::set<std::string>{"rgb_00267.jpg.kpt", "rgb_00481.jpg.kpt", "rgb_00491.jpg.kpt"}));
  const std::string failures = testing::ReadText(partial / "failures.txt");
  EXPECT_TRUE(Has(failures, std::string(kBad) + ", ")) << failures;
  EXPECT_TRUE(Has(failures, "truncated JPEG")) << failures;
  EXPECT_TRUE(Has(log, (partial / "failures.txt").string())) << log;

  // The report's warnings name the image and the reason.
  ASSERT_EQ(testing::RunHost(bin, {"report", ws.string(), "-o", (dir / "report.html").string()},
                             dir / "report.log"),
            0)
      << testing::ReadText(dir / "report.log");
  const std::string report = testing::ReadText(dir / "report.html");
  EXPECT_FALSE(Has(report, "No warnings")) << report;
  EXPECT_TRUE(Has(report, "rgb_00446.jpg")) << report;
  EXPECT_TRUE(Has(report, "truncated JPEG")) << report;

  // kapture info --check-images: the damaged copy listed (exit 1), the source clean.
  const auto info_of = [&](const fs::path& kapture, const fs::path& log) {
    return testing::RunHost(bin, {"kapture", "info", kapture.string(), "--check-images"}, log);
  };
  EXPECT_EQ(info_of(copy, dir / "info.log"), 1);
  const std::string info = testing::ReadText(dir / "info.log");
  EXPECT_TRUE(Has(info, "images checked: 4, damaged: 1")) << info;
  EXPECT_TRUE(Has(info, "damaged image ")) << info;
  EXPECT_TRUE(Has(info, std::string(kBad) + ": truncated JPEG")) << info;
  EXPECT_EQ(info_of(source, dir / "info2.log"), 0)
      << testing::ReadText(dir / "info2.log");
  EXPECT_TRUE(Has(testing::ReadText(dir / "info2.log"), "images checked: 4, damaged: 0"));
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace locforge

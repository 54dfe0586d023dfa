// configs/benchmark/sift_densevlad.yaml end to end through the host, on the
// simulator's `tiny` recording generated here (known ground truth): the map
// kapture and the validation + test query kaptures merged into one query set,
// SIFT + DenseVLAD, COLMAP point_triangulator, both solvers on the same
// matches, eval/localization by camera group and split, eval/table. Then a
// second variant (top_k changed) must reuse the cached features. About one
// CPU-minute (measured 58 s user for the whole test on the shared machine).
#include <gtest/gtest.h>

#include <cstdlib>
#include <map>
#include <sstream>

#include "../testing/testing.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"

namespace locforge {
namespace {

namespace kp = locforge::kapture;

using testing::ReadCsv;

// Rows of summary.csv keyed by "group/split".
std::map<std::string, std::vector<std::string>> Summary(const fs::path& report) {
  const auto rows = ReadCsv(report / "summary.csv");
  EXPECT_GE(rows.size(), 2u);
  EXPECT_EQ(rows[0][0], "method");
  EXPECT_EQ(rows[0].size(), 10u);  // method group split queries localized 3 thresholds 2 medians
  EXPECT_EQ(rows[0][6], "0.25m,2deg");
  std::map<std::string, std::vector<std::string>> out;
  for (size_t i = 1; i < rows.size(); ++i) out[rows[i][1] + "/" + rows[i][2]] = rows[i];
  return out;
}

int CacheEntries(const fs::path& ws, const std::string& node) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(ws / "cache")) {
    const std::string name = e.path().filename().string();
    if (name.rfind(node + "-", 0) == 0 && name.find(".partial") == std::string::npos &&
        name.size() == node.size() + 17)
      ++n;
  }
  return n;
}

// `locforge kapture export` of the benchmark's map (its default nodes): one
// kapture that `kapture info --strict` finds clean and that holds what the
// nodes hold, keypoints byte for byte, records linked to the map's files.
void ExpectExportOfTheMap(const fs::path& bin, const fs::path& ws, const fs::path& dir) {
  const fs::path out = dir / "export";
  ASSERT_EQ(testing::RunHost(bin, {"kapture", "export", ws.string(), out.string()}, dir / "export.log"), 0)
      << ReadFile(dir / "export.log");
  EXPECT_NE(ReadFile(dir / "export.log").find("nodes (default): map,map_features,map_verified,map_global,triangulation"),
            std::string::npos)
      << ReadFile(dir / "export.log");
  ASSERT_EQ(testing::RunHost(bin, {"kapture", "info", "--strict", out.string()}, dir / "info.log"), 0)
      << ReadFile(dir / "info.log");
  EXPECT_EQ(ReadFile(out / "sensors/sensors.txt").rfind("# kapture format: 1.1\n", 0), 0u);
  const kp::Kapture ex(out), map(ws / "nodes/map"), features(ws / "nodes/map_features"),
      matches(ws / "nodes/map_verified"), global(ws / "nodes/map_global"), mapper(ws / "nodes/triangulation");
  EXPECT_EQ(ex.CameraImages(), map.CameraImages());
  EXPECT_EQ(ex.trajectories().size(), map.trajectories().size());
  EXPECT_EQ(ex.sensors().size(), map.sensors().size());
  for (const kp::FeatureKind kind : {kp::FeatureKind::kKeypoints, kp::FeatureKind::kDescriptors,
                                     kp::FeatureKind::kGlobalFeatures}) {
    const kp::Kapture& node = kind == kp::FeatureKind::kGlobalFeatures ? global : features;
    const auto sets = node.FeatureSets(kind);
    ASSERT_EQ(sets.size(), 1u);
    const std::vector<std::string> images = node.FeatureImages(kind, sets[0].type);
    EXPECT_EQ(ex.FeatureImages(kind, sets[0].type), images);
    EXPECT_EQ(images.size(), map.CameraImages().size());
    if (kind != kp::FeatureKind::kKeypoints) continue;
    EXPECT_TRUE(fs::exists(out / "reconstruction/keypoints" / sets[0].type / "keypoints.txt"));
    for (const std::string& image : images)
      EXPECT_EQ(ReadFile(ex.FeatureFile(kind, sets[0].type, image)), ReadFile(node.FeatureFile(kind, sets[0].type, image)))
          << image;
  }
  const std::string type = matches.MatchesTypes().at(0);
  EXPECT_EQ(ex.MatchPairs(type), matches.MatchPairs(type));
  EXPECT_GT(ex.MatchPairs(type).size(), 0u);
  EXPECT_EQ(ex.points3d().size(), mapper.points3d().size());
  EXPECT_GT(ex.points3d().size(), 0u);
  EXPECT_EQ(ex.observations().size(), mapper.observations().size());
  const auto record = ex.ReadDataRecords(kp::kSensorCamera).at(0);
  const fs::path image = out / "sensors/records_data" / record.path;
  EXPECT_TRUE(fs::is_symlink(image));
  EXPECT_EQ(fs::read_symlink(image), fs::canonical(ws / "nodes/map/sensors/records_data" / record.path));

  // A second export over it needs --force; two nodes holding different
  // camera records are refused, naming both.
  EXPECT_EQ(testing::RunHost(bin, {"kapture", "export", ws.string(), out.string()}, dir / "export2.log"), 2);
  EXPECT_EQ(testing::RunHost(bin, {"kapture", "export", ws.string(), out.string(), "--force", "--copy"},
                             dir / "export3.log"),
            0)
      << ReadFile(dir / "export3.log");
  EXPECT_FALSE(fs::is_symlink(out / "sensors/records_data" / record.path));
  EXPECT_EQ(testing::RunHost(bin, {"kapture", "export", ws.string(), (dir / "both").string(), "--nodes", "map,query"},
                             dir / "export4.log"),
            2);
  EXPECT_NE(ReadFile(dir / "export4.log").find("nodes 'map' and 'query'"), std::string::npos)
      << ReadFile(dir / "export4.log");
  EXPECT_FALSE(fs::exists(dir / "both"));
}

TEST(BenchmarkE2E, SiftDenseVladBothSolversOnTinySimulator) {
  const fs::path bin = LOCFORGE_BINARY_DIR;
  const fs::path dir = testing::MakeTempDir("benchmark_e2e");
  // The recording: tiny preset at twice its image size (324x256 industrial):
  // 152 map images, 76 validation + 76 test queries.
  const fs::path rec = testing::SimulateRecording(
      bin, dir, "{preset: tiny, seed: 0, scale: 0.125, lidar: false, masks: false}");
  ASSERT_FALSE(rec.empty()) << ReadFile(dir / "sim.log");
  const fs::path config = fs::path(LOCFORGE_SOURCE_DIR) / "configs/benchmark/sift_densevlad.yaml";
  const fs::path ws = dir / "ws";
  const std::vector<std::string> common = {
      "run", config.string(), "--workspace", ws.string(), "--threads", "2",
      "--set", "map=" + rec.string(), "--set", "map_subfolders=[.]",
      "--set", "query=" + rec.string(), "--set", "query_subfolders=[validation, test]",
      "--set", "groups=[industrial=ind_.*, smartphone=phone_.*]",
      "--set", "splits=[validation=validation/.*, test=test/.*]",
      "--set", "vocabulary.clusters=16", "--set", "vocabulary.sample_size=20000",
      "--set", "vocabulary.max_image_size=160", "--set", "vocabulary.grid_step=8"};
  const auto run = [&](const std::string& top_k, const std::string& log) {
    std::vector<std::string> args = common;
    args.insert(args.end(), {"--set", "top_k=" + top_k});
    return testing::RunHost(bin, args, dir / log);
  };
  ASSERT_EQ(run("10", "bench.log"), 0) << ReadFile(dir / "bench.log");

  // Queries: every image of both query kaptures, paths prefixed by their split.
  kp::Kapture query(ws / "nodes/query");
  const auto images = query.ReadDataRecords(kp::kSensorCamera);
  const size_t expected = kp::Kapture(rec / "validation").ReadDataRecords(kp::kSensorCamera).size() +
                          kp::Kapture(rec / "test").ReadDataRecords(kp::kSensorCamera).size();
  ASSERT_EQ(images.size(), expected);
  ASSERT_GT(images.size(), 20u);

  for (const std::string solver : {"pnp", "colmap_registrator"}) {
    SCOPED_TRACE(solver);
    // Estimated poses as kapture trajectories; every query either has a pose
    // or is listed as a failure, never both.
    const fs::path node = ws / "nodes" / solver;
    kp::Kapture est(node);
    ASSERT_TRUE(fs::exists(node / "sensors/trajectories.txt"));
    std::istringstream failures(ReadFile(node / "failures.txt"));
    std::string line;
    size_t failed = 0;
    while (std::getline(failures, line))
      if (!line.empty() && line[0] != '#') ++failed;
    size_t localized = 0;
    for (const auto& r : images) localized += est.DevicePose(r.timestamp, r.device_id) ? 1 : 0;
    EXPECT_EQ(localized + failed, images.size());
    EXPECT_EQ(est.trajectories().size(), localized);

    // The evaluation: buckets by camera group and split, recall as measured.
    const fs::path report = ws / "nodes" / (solver == "pnp" ? "eval_pnp" : "eval_colmap");
    const auto summary = Summary(report);
    for (const char* key : {"all/all", "industrial/all", "smartphone/all", "all/validation",
                            "all/test", "industrial/validation", "smartphone/test"})
      EXPECT_TRUE(summary.count(key)) << key;
    const auto& all = summary.at("all/all");
    EXPECT_EQ(std::stoul(all[3]), images.size());
    EXPECT_EQ(std::stoul(all[4]), localized);
    EXPECT_EQ(std::stoul(summary.at("all/validation")[3]) + std::stoul(summary.at("all/test")[3]),
              images.size());
    for (const auto& [key, row] : summary)
      std::cout << solver << " " << key << ": " << row[4] << " / " << row[3] << " localized, "
                << row[5] << " / " << row[6] << " / " << row[7] << " %, median " << row[8]
                << " m " << row[9] << " deg\n";
    // Simulator 0.2.0: both query sequences revisit a mapped stretch of their
    // area. Measured within (0.25 m, 2 deg): pnp 100 % validation, 100 % test;
    // image_registrator 100 %, 98.7 %; median errors 2-4 mm, 0.03-0.04 deg.
    for (const char* split : {"all/validation", "all/test"})
      EXPECT_GE(std::stod(summary.at(split)[6]), 90.0) << split;
    EXPECT_EQ(ReadCsv(report / "per_query.csv").size(), images.size() + 1);
    for (const char* f : {"summary.md", "summary.tex", "curve.svg", "curve.png"})
      EXPECT_TRUE(fs::exists(report / f)) << f;
    const std::string png = ReadFile(report / "curve.png");
    EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  }
  const auto table = ReadCsv(ws / "nodes/table/table.csv");
  ASSERT_EQ(table.size(), 3u);  // header + the two solvers
  EXPECT_EQ(table[0][0], "method");
  EXPECT_EQ(table[1][0], "sift+densevlad pnp");
  EXPECT_EQ(table[2][0], "sift+densevlad image_registrator");
  EXPECT_TRUE(fs::exists(ws / "nodes/table/table.md"));
  EXPECT_TRUE(fs::exists(ws / "nodes/table/table.tex"));
  ExpectExportOfTheMap(bin, ws, dir);

  // A second variant (fewer retrieved pairs): features and the vocabulary come
  // from the cache, the pairs and everything after them are recomputed.
  ASSERT_EQ(run("5", "bench2.log"), 0) << ReadFile(dir / "bench2.log");
  for (const char* node : {"map_features", "query_features", "vocabulary", "map_global"})
    EXPECT_EQ(CacheEntries(ws, node), 1) << node;
  for (const char* node : {"map_pairs", "query_pairs", "triangulation", "pnp"})
    EXPECT_EQ(CacheEntries(ws, node), 2) << node;
  fs::remove_all(dir);
}

// COLMAP classic's figures on one protocol (a kapture localization pair under
// ../shared), measured once: the floor our default recipe must hold.
struct ColmapClassicFloor {
  const char* protocol;   // folder under ../shared holding mapping/ and query/
  int queries;
  double recall[3];       // % at (0.1 m, 1 deg), (0.25 m, 2 deg), (1 m, 5 deg)
  double median_m;        // median position error of COLMAP's registered queries
  double median_deg;      // median rotation error
};

// Runs configs/benchmark/sift_densevlad.yaml (the default recipe, nothing set
// but the data) on the protocol and checks pnp, the default solver, against
// the floor: recall at least COLMAP classic's at every threshold, medians at
// most COLMAP's. image_registrator on the same matches is printed beside it.
void ExpectAtLeastColmapClassic(const ColmapClassicFloor& floor) {
  LOCFORGE_SHARED_PATH_OR_SKIP(shared, floor.protocol);
  const fs::path bin = LOCFORGE_BINARY_DIR;
  const fs::path dir = testing::MakeTempDir("benchmark_real");
  const fs::path config = fs::path(LOCFORGE_SOURCE_DIR) / "configs/benchmark/sift_densevlad.yaml";
  ASSERT_EQ(testing::RunHost(bin, {"run", config.string(), "--workspace", (dir / "ws").string(), "--threads", "2",
                                   "--set", "map=" + (shared / "mapping").string(), "--set",
                                   "query=" + (shared / "query").string()},
                              dir / "run.log"),
            0)
      << ReadFile(dir / "run.log");
  for (const char* report : {"eval_pnp", "eval_colmap"}) {
    const auto all = Summary(dir / "ws/nodes" / report).at("all/all");
    std::cout << floor.protocol << " " << report << ": " << all[5] << " / " << all[6] << " / " << all[7]
              << " %, median " << all[8] << " m / " << all[9] << " deg (COLMAP classic: " << floor.recall[0]
              << " / " << floor.recall[1] << " / " << floor.recall[2] << " %, " << floor.median_m << " m / "
              << floor.median_deg << " deg)\n";
    EXPECT_EQ(std::stoi(all[3]), floor.queries) << report;
  }
  const auto pnp = Summary(dir / "ws/nodes/eval_pnp").at("all/all");
  for (int i = 0; i < 3; ++i)
    EXPECT_GE(std::stod(pnp[5 + i]), floor.recall[i]) << floor.protocol << ": recall below COLMAP classic's at threshold " << i;
  EXPECT_LE(std::stod(pnp[8]), floor.median_m) << floor.protocol << ": median position error above COLMAP classic's";
  EXPECT_LE(std::stod(pnp[9]), floor.median_deg) << floor.protocol << ": median rotation error above COLMAP classic's";
  fs::remove_all(dir);
}

// The floors come from the protocol suite (configs/benchmark/README.md, "The
// protocol suite"), COLMAP 3.8 classic at --threads 2 on the 2-core machine:
//   python3 configs/benchmark/suite.py --workspace SUITE --methods colmap_classic \
//       --protocols virtual_gallery_tutorial,strecha_castle-P30_sparse,strecha_entry-P10
// COLMAP classic is not deterministic: each floor is the better of the runs
// measured, figure by figure (Virtual Gallery: 2.07 mm on 2026-12-03,
// 0.0310 deg on 2026-12-07; entry: 2026-12-06).
TEST(BenchmarkE2E, VirtualGalleryAtLeastColmapClassic) {
  ExpectAtLeastColmapClassic({"data/kapture/virtual_gallery_tutorial", 4, {100, 100, 100}, 0.00207, 0.0310});
}

// Real photographs with LiDAR-registered poses: a sparse map of a courtyard
// (wide baselines, a facade repeated on four sides; COLMAP classic is not
// deterministic there: 62.5 % in the suite's run, 75 % in an earlier one, and
// the floor is the better of the two, recall and medians alike), and the few
// views of a building's entry (strong depth changes).
TEST(BenchmarkE2E, StrechaCastleSparseAtLeastColmapClassic) {
  ExpectAtLeastColmapClassic({"data/localization/strecha_castle-P30_sparse", 24, {75, 75, 75}, 0.028, 0.046});
}

TEST(BenchmarkE2E, StrechaEntryAtLeastColmapClassic) {
  ExpectAtLeastColmapClassic({"data/localization/strecha_entry-P10", 5, {100, 100, 100}, 0.00677, 0.0216});
}

}  // namespace
}  // namespace locforge

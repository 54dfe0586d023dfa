// Retrieval with known answers: the sample's own AP-GeM descriptors give the
// top-1 their cosine ranking gives and a map image near the query; DenseVLAD
// on the simulator's tiny preset retrieves map images near the queries;
// pose proximity, exhaustive and file pairs; plugin conformance.
#include <gtest/gtest.h>

#include <fstream>
#include <cmath>
#include <map>
#include <opencv2/core.hpp>
#include <random>
#include <sstream>
#include <tuple>

#include "densevlad.h"
#include "locforge/kapture/kapture.h"
#include "locforge/runtime/registry.h"
#include "locforge/testkit.h"
#include "testing.h"

namespace locforge::retrieval {
namespace {

namespace k = locforge::kapture;

using testkit::RunStage;

struct Pair {
  std::string query, map;
  double score;
};
std::vector<Pair> ReadPairs(const fs::path& folder) {
  k::CsvReader reader(folder / "pairs.txt");
  std::vector<Pair> out;
  k::CsvRow row;
  while (reader.Next(&row)) out.push_back({row.fields[0], row.fields[1], std::stod(row.fields[2])});
  return out;
}

std::map<std::string, Eigen::Vector3d> Centres(const fs::path& dataset) {
  k::Kapture kap(dataset);
  std::map<std::string, Eigen::Vector3d> out;
  for (const auto& r : kap.ReadDataRecords("camera")) {
    const auto pose = kap.DevicePose(r.timestamp, r.device_id);
    if (pose) out[r.path] = pose->Center();
  }
  return out;
}

// Loads the global and pairs plugins into `registry` and imports the sample's
// own AP-GeM-LM18 descriptors into `dir` (kapture.global_features).
void ImportSampleApGem(runtime::Registry& registry, const fs::path& shared, const fs::path& dir) {
  for (const char* f : {LOCFORGE_GLOBAL_PLUGIN_FILE, LOCFORGE_PAIRS_PLUGIN_FILE})
    ASSERT_TRUE(registry.LoadFile(f));
  RunStage(registry, "global/import", {{"path", (shared / "global_features/AP-GeM-LM18").string()}}, {}, dir);
}

TEST(PairsRetrieval, SampleApGemTop1IsTheCosineTop1AndNearby) {
  LOCFORGE_SHARED_PATH_OR_SKIP(shared, "data/kapture/virtual_gallery_tutorial");
  const fs::path tmp = locforge::testing::MakeTempDir("retrieval_apgem");
  runtime::Registry registry;
  ASSERT_NO_FATAL_FAILURE(ImportSampleApGem(registry, shared, tmp / "gfeat"));
  const runtime::InputArtifact gf{"map_features", "kapture.global_features", tmp / "gfeat"};
  const runtime::InputArtifact qf{"query_features", "kapture.global_features", tmp / "gfeat"};
  const runtime::InputArtifact map{"map", "kapture.dataset", shared / "mapping"};
  const runtime::InputArtifact query{"query", "kapture.dataset", shared / "query"};
  RunStage(registry, "pairs/retrieval", {{"topk", "5"}}, {gf, qf, map, query}, tmp / "q2m");
  RunStage(registry, "pairs/retrieval", {{"topk", "3"}}, {gf, map}, tmp / "m2m");

  // Independent ranking straight from the .gfeat files.
  const k::Kapture sample_gf(tmp / "gfeat");
  auto read = [&](const std::string& image) {
    const auto a = sample_gf.ReadGlobalFeatures("AP-GeM-LM18", image);
    Eigen::VectorXd v(a.dsize);
    for (int64_t i = 0; i < a.dsize; ++i) v[i] = a.At(0, i);
    return v.normalized();
  };
  const auto map_centres = Centres(shared / "mapping");
  const auto query_centres = Centres(shared / "query");
  ASSERT_EQ(map_centres.size(), 12u);
  ASSERT_EQ(query_centres.size(), 4u);
  const auto pairs = ReadPairs(tmp / "q2m");
  ASSERT_EQ(pairs.size(), 4u * 5u);
  for (const auto& [q, qc] : query_centres) {
    std::string best;
    double best_score = -2;
    for (const auto& [m, mc] : map_centres) {
      const double s = read(q).dot(read(m));
      if (s > best_score) best_score = s, best = m;
    }
    auto first = std::find_if(pairs.begin(), pairs.end(), [&](const Pair& p) { return p.query == q; });
    ASSERT_NE(first, pairs.end());
    EXPECT_EQ(first->map, best);
    EXPECT_NEAR(first->score, best_score, 1e-6);
    const double distance = (map_centres.at(first->map) - qc).norm();
    std::cout << q << " -> " << first->map << " score " << first->score << ", centres " << distance
              << " m apart\n";
    EXPECT_LT(distance, 5.0);
  }
  // Map-to-map: 12 x 3 pairs, never an image with itself, scores decreasing.
  const auto m2m = ReadPairs(tmp / "m2m");
  ASSERT_EQ(m2m.size(), 36u);
  for (size_t i = 0; i < m2m.size(); ++i) {
    EXPECT_NE(m2m[i].query, m2m[i].map);
    EXPECT_TRUE(map_centres.count(m2m[i].map));
    if (i % 3) EXPECT_LE(m2m[i].score, m2m[i - 1].score);
  }
  fs::remove_all(tmp);
}

// pairs/retrieval is per item (blocks of queries): one query per item over 3
// shards, each shard its own stage instance as a separate process would be,
// must write the same pairs.txt, byte for byte, as one unsharded run with the
// same blocks; the shard that finds every item journaled is the one that
// writes it. Other blocks (256 queries) rank the same pairs; their scores may
// differ in the last float bits (Eigen sums a 1-row product in another order).
TEST(PairsRetrieval, ShardedBlocksWriteTheSamePairsAsOneRun) {
  LOCFORGE_SHARED_PATH_OR_SKIP(shared, "data/kapture/virtual_gallery_tutorial");
  const fs::path tmp = locforge::testing::MakeTempDir("retrieval_shards");
  runtime::Registry registry;
  ASSERT_NO_FATAL_FAILURE(ImportSampleApGem(registry, shared, tmp / "gfeat"));
  const std::vector<runtime::InputArtifact> inputs = {
      {"map_features", "kapture.global_features", tmp / "gfeat"}, {"map", "kapture.dataset", shared / "mapping"}};
  const auto whole = RunStage(registry, "pairs/retrieval", {{"topk", "4"}, {"queries_per_item", "1"}}, inputs,
                              tmp / "whole");
  EXPECT_EQ(whole.items_total, 12u);
  const auto one_block = RunStage(registry, "pairs/retrieval", {{"topk", "4"}}, inputs, tmp / "one_block");
  EXPECT_EQ(one_block.items_total, 1u);  // 12 map images, 256 a block
  const auto pairs = ReadPairs(tmp / "whole"), pairs_one_block = ReadPairs(tmp / "one_block");
  ASSERT_EQ(pairs.size(), 12u * 4u);
  ASSERT_EQ(pairs_one_block.size(), pairs.size());
  for (size_t i = 0; i < pairs.size(); ++i) {
    EXPECT_EQ(pairs[i].query, pairs_one_block[i].query);
    EXPECT_EQ(pairs[i].map, pairs_one_block[i].map);
    EXPECT_NEAR(pairs[i].score, pairs_one_block[i].score, 1e-6);
  }

  const runtime::StageEntry* stage = registry.Find("pairs/retrieval");
  ASSERT_NE(stage, nullptr);
  const auto params = runtime::CheckStageParams(*stage, {{"topk", "4"}, {"queries_per_item", "1"}});
  uint64_t items = 0;
  int completed_by = -1;
  // One shard as its own process would run it: a fresh stage instance.
  auto run_shard = [&](int shard, int shards) {
    runtime::StageInstance instance(*stage, params);
    runtime::RunOptions run;
    run.workspace = tmp;
    run.output_dir = tmp / "sharded";
    run.inputs = inputs;
    run.threads = 2;
    run.shard_index = shard;
    run.shard_count = shards;
    return instance.Run(run);
  };
  for (int shard : {2, 0, 1}) {
    const auto result = run_shard(shard, 3);
    items += result.items_total;
    if (result.complete) completed_by = shard;
    EXPECT_EQ(fs::exists(tmp / "sharded" / "pairs.txt"), result.complete) << "shard " << shard;
  }
  EXPECT_EQ(items, 12u);  // one item per map image, each in one shard
  EXPECT_EQ(completed_by, 1);
  EXPECT_EQ(ReadFile(tmp / "sharded" / "pairs.txt"), ReadFile(tmp / "whole" / "pairs.txt"));

  // A lost block (an interrupted shard) is recomputed by a rerun that forgets its journal entry.
  fs::remove(tmp / "sharded" / "blocks" / "queries-000005.txt");
  fs::remove(tmp / "sharded" / "pairs.txt");
  for (const auto& entry : fs::directory_iterator(tmp / "sharded"))
    if (entry.path().filename().string().rfind(".items-done.", 0) == 0) {
      std::string kept;
      std::istringstream lines(ReadFile(entry.path()));
      for (std::string line; std::getline(lines, line);)
        if (line != "queries-000005") kept += line + "\n";
      WriteFileAtomic(entry.path(), kept);
    }
  const auto result = run_shard(0, 1);
  EXPECT_TRUE(result.complete);
  EXPECT_EQ(result.items_processed, 1u);
  EXPECT_EQ(ReadFile(tmp / "sharded" / "pairs.txt"), ReadFile(tmp / "whole" / "pairs.txt"));
  fs::remove_all(tmp);
}

TEST(PairsGeometry, ExhaustiveAndPoseProximityOnTheSample) {
  LOCFORGE_SHARED_PATH_OR_SKIP(shared, "data/kapture/virtual_gallery_tutorial");
  const fs::path tmp = locforge::testing::MakeTempDir("pairs_geometry");
  runtime::Registry registry;
  for (const char* f : {LOCFORGE_GLOBAL_PLUGIN_FILE, LOCFORGE_PAIRS_PLUGIN_FILE})
    ASSERT_TRUE(registry.LoadFile(f));
  const runtime::InputArtifact map{"map", "kapture.dataset", shared / "mapping"};
  const runtime::InputArtifact query{"query", "kapture.dataset", shared / "query"};
  RunStage(registry, "pairs/exhaustive", {}, {map}, tmp / "ex_m");
  RunStage(registry, "pairs/exhaustive", {}, {map, query}, tmp / "ex_q");
  EXPECT_EQ(ReadPairs(tmp / "ex_m").size(), 66u);
  EXPECT_EQ(ReadPairs(tmp / "ex_q").size(), 48u);

  RunStage(registry, "pairs/pose_proximity", {{"max_distance_m", "1.5"}, {"max_angle_deg", "70"}},
           {map, query}, tmp / "prox");
  // Brute force with the same thresholds.
  k::Kapture mk(shared / "mapping"), qk(shared / "query");
  auto views = [](const k::Kapture& kap) {
    std::map<std::string, Pose> out;
    for (const auto& r : kap.ReadDataRecords("camera")) out[r.path] = *kap.DevicePose(r.timestamp, r.device_id);
    return out;
  };
  size_t expected = 0;
  for (const auto& [q, qp] : views(qk))
    for (const auto& [m, mp] : views(mk)) {
      const double d = (qp.Center() - mp.Center()).norm();
      const double angle = RotationAngleDeg(qp.q, mp.q);  // >= the optical-axis angle
      const Eigen::Vector3d za = qp.R().transpose().col(2), zb = mp.R().transpose().col(2);
      (void)angle;
      if (d <= 1.5 && za.dot(zb) >= std::cos(70 * M_PI / 180)) ++expected;
    }
  const auto prox = ReadPairs(tmp / "prox");
  std::cout << prox.size() << " query-map pairs within 1.5 m and 70 deg\n";
  EXPECT_EQ(prox.size(), expected);
  EXPECT_GT(expected, 0u);
  fs::remove_all(tmp);
}

// Two passes along the same corridor 100 s apart, 4 cameras per moment: the
// closest images of every image are those of its own moment, so top-k alone
// never pairs the passes; topk_revisit must, whatever the names' order.
TEST(PairsGeometry, PoseProximityRevisitsAcrossSequences) {
  const fs::path tmp = locforge::testing::MakeTempDir("pairs_revisit");
  std::string records = "# kapture format: 1.1\n", poses = "# kapture format: 1.1\n";
  std::string sensors = "# kapture format: 1.1\n";
  for (int c = 0; c < 4; ++c) sensors += "cam" + std::to_string(c) + ", c, camera, PINHOLE, 64, 48, 50, 50, 32, 24\n";
  const std::vector<std::tuple<std::string, int64_t, double>> passes = {{"z_first", 0, 0.0},
                                                                         {"a_second", 100000000, 0.3}};
  for (const auto& [seq, t0, y] : passes)
    for (int k = 0; k < 10; ++k)
      for (int c = 0; c < 4; ++c) {
        const int64_t t = t0 + k * 1000000 + c;
        records += std::to_string(t) + ", cam" + std::to_string(c) + ", " + seq + "/" + std::to_string(t) + ".jpg\n";
        // Camera at (k, y + 0.01 c, 0) looking along +x (kapture stores camera-from-world).
        const Pose T_world_cam(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY())),
                               Eigen::Vector3d(k, y + 0.01 * c, 0));
        const Pose T_cam_world = T_world_cam.Inverse();
        char line[256];
        std::snprintf(line, sizeof(line), "%lld, cam%d, %.12f, %.12f, %.12f, %.12f, %.12f, %.12f, %.12f\n",
                      static_cast<long long>(t), c, T_cam_world.q.w(), T_cam_world.q.x(), T_cam_world.q.y(),
                      T_cam_world.q.z(), T_cam_world.t.x(), T_cam_world.t.y(), T_cam_world.t.z());
        poses += line;
      }
  WriteFileAtomic(tmp / "map/sensors/sensors.txt", sensors);
  WriteFileAtomic(tmp / "map/sensors/records_camera.txt", records);
  WriteFileAtomic(tmp / "map/sensors/trajectories.txt", poses);
  runtime::Registry registry;
  for (const char* f : {LOCFORGE_GLOBAL_PLUGIN_FILE, LOCFORGE_PAIRS_PLUGIN_FILE})
    ASSERT_TRUE(registry.LoadFile(f));
  const runtime::InputArtifact map{"map", "kapture.dataset", tmp / "map"};
  auto cross = [](const std::vector<Pair>& pairs) {
    int n = 0;
    for (const auto& p : pairs) n += p.query.substr(0, 2) != p.map.substr(0, 2);
    return n;
  };
  RunStage(registry, "pairs/pose_proximity", {{"max_distance_m", "2"}, {"topk", "3"}}, {map}, tmp / "top3");
  const auto top3 = ReadPairs(tmp / "top3");
  EXPECT_EQ(cross(top3), 0);  // the 3 closest: the other cameras of the same moment
  // Every image has the same number of neighbours kept, whatever its name: 80 images x 3, each pair once.
  EXPECT_EQ(top3.size(), 120u);
  RunStage(registry, "pairs/pose_proximity", {{"max_distance_m", "2"}, {"topk", "3"}, {"topk_revisit", "2"}}, {map},
           tmp / "revisit");
  const auto revisit = ReadPairs(tmp / "revisit");
  // 2 revisits per image, 80 images, each cross pair found from both sides at most once.
  EXPECT_GE(cross(revisit), 80);
  EXPECT_EQ(revisit.size() - cross(revisit), top3.size());
  fs::remove_all(tmp);
}

TEST(PairsFile, RefusesABadLineNamingIt) {
  const fs::path tmp = locforge::testing::MakeTempDir("pairs_file");
  WriteFileAtomic(tmp / "in.txt", "# query_image, map_image, score\na.jpg, b.jpg, 0.5\nc.jpg\n");
  runtime::Registry registry;
  for (const char* f : {LOCFORGE_GLOBAL_PLUGIN_FILE, LOCFORGE_PAIRS_PLUGIN_FILE})
    ASSERT_TRUE(registry.LoadFile(f));
  try {
    RunStage(registry, "pairs/file", {{"path", (tmp / "in.txt").string()}}, {}, tmp / "out");
    ADD_FAILURE() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(":3"), std::string::npos) << e.what();
  }
  WriteFileAtomic(tmp / "in.txt", "a.jpg, b.jpg, 0.5\nc.jpg, d.jpg\n");
  RunStage(registry, "pairs/file", {{"path", (tmp / "in.txt").string()}}, {}, tmp / "out2");
  const auto pairs = ReadPairs(tmp / "out2");
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[1].score, 1.0);
  fs::remove_all(tmp);
}

TEST(DenseVlad, VladIsNormalisedAndVocabularyRoundTrips) {
  std::mt19937 rng(4);
  std::normal_distribution<float> g;
  RowMatrix x(3000, 128);
  for (int i = 0; i < x.rows(); ++i)
    for (int j = 0; j < 128; ++j) x(i, j) = std::abs(g(rng)) + (i % 3) * (j % 7 == 0);
  Vocabulary v;
  v.centres = KMeans(x, 8, 10, 1);
  EXPECT_TRUE(v.centres.isApprox(KMeans(x, 8, 10, 1)));  // deterministic
  const Eigen::VectorXf vlad = Vlad(x.topRows(500), v.centres);
  EXPECT_EQ(vlad.size(), 8 * 128);
  EXPECT_NEAR(vlad.norm(), 1.0, 1e-5);
  RowMatrix vlads(20, 8 * 128);
  for (int i = 0; i < 20; ++i) vlads.row(i) = Vlad(x.middleRows(100 * i, 300), v.centres).transpose();
  LearnPcaWhitening(vlads, 10, &v);
  EXPECT_EQ(v.Dimension(), 10);
  // Whitened training projections have (nearly) equal variance per component.
  const Eigen::MatrixXf y = (vlads.rowwise() - v.pca_mean.transpose()) * v.pca_projection.transpose();
  const Eigen::VectorXf var = y.colwise().squaredNorm();
  EXPECT_NEAR(var.maxCoeff() / var.minCoeff(), 1.0, 1e-2);
  const Vocabulary back = Vocabulary::Parse(v.Serialize(), "v.bin");
  EXPECT_TRUE(back.centres.isApprox(v.centres));
  EXPECT_TRUE(back.pca_projection.isApprox(v.pca_projection));
  EXPECT_THROW(Vocabulary::Parse(v.Serialize().substr(0, 500), "v.bin"), InputError);
}

// Row of the grid point (x, y) in DenseRootSift's output for one bin size at
// grid step 1: rows run over y then x, from ceil(2 bin) inside the border.
int64_t GridRow(const cv::Mat& image, double bin, int x, int y) {
  const int m = static_cast<int>(std::ceil(2 * bin));
  return static_cast<int64_t>(y - m) * (image.cols - 2 * m) + (x - m);
}

// A linear ramp's gradient has one orientation everywhere: every spatial bin
// holds the same value in that orientation (RootSIFT: 1/sqrt(16) = 0.25), or,
// half-way between two of the 8 orientations, half in each (1/sqrt(32)).
TEST(DenseVlad, DenseSiftOfARampIsItsOrientationInEveryBin) {
  DenseSiftOptions o;
  o.max_image_size = 0;
  o.grid_step = 1;
  o.bin_sizes = {6};
  const double pi = std::acos(-1.0);
  for (const auto& [angle_deg, first, second] : {std::tuple{0.0, 0, 0}, std::tuple{90.0, 2, 2},
                                                  std::tuple{180.0, 4, 4}, std::tuple{22.5, 0, 1},
                                                  std::tuple{292.5, 6, 7}}) {
    SCOPED_TRACE("ramp at " + std::to_string(angle_deg) + " deg");
    cv::Mat image(96, 96, CV_8U);
    const double c = std::cos(angle_deg * pi / 180), sn = std::sin(angle_deg * pi / 180);
    for (int y = 0; y < image.rows; ++y)  // image y points down, as the gradient's angle does
      for (int x = 0; x < image.cols; ++x) image.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(128 + 2.0 * ((x - 48) * c + (y - 48) * sn));
    const RowMatrix d = DenseRootSift(image, o);
    const Eigen::VectorXf at = d.row(GridRow(image, 6, 48, 48)).transpose();
    const float expected = first == second ? 0.25f : 1 / std::sqrt(32.f);
    for (int b = 0; b < 16; ++b)
      for (int k = 0; k < 8; ++k) {
        const bool lit = k == first || k == second;
        EXPECT_NEAR(at[b * 8 + k], lit ? expected : 0.f, 0.03) << "spatial bin " << b << " orientation " << k;
      }
  }
}

// Each of the 4x4 spatial bins sees only the pixels within one bin width of
// its centre: a ramp that stops 2 bins left of the descriptor's centre (its
// edge) lights the first column of bins only; the same ramp above, the first row.
TEST(DenseVlad, DenseSiftBinsSeeOnlyTheirOwnPartOfTheImage) {
  DenseSiftOptions o;
  o.max_image_size = 0;
  o.grid_step = 1;
  o.bin_sizes = {8};
  const int centre = 64;
  for (bool columns : {true, false}) {
    cv::Mat image(128, 128, CV_8U);
    for (int y = 0; y < image.rows; ++y)
      for (int x = 0; x < image.cols; ++x) {
        const int u = columns ? x : y;  // the ramp runs along u up to centre - 16 (2 bins), then flat
        image.at<uint8_t>(y, x) = static_cast<uint8_t>(std::min(u, centre - 16) * 2);
      }
    const RowMatrix d = DenseRootSift(image, o);
    const Eigen::VectorXf at = d.row(GridRow(image, 8, centre, centre)).transpose();
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        float mass = 0;
        for (int k = 0; k < 8; ++k) mass += at[(i * 4 + j) * 8 + k];
        const bool lit = (columns ? j : i) == 0;
        if (lit)
          EXPECT_GT(mass, 0.4f) << "bin " << i << "," << j;
        else
          EXPECT_LT(mass, 0.05f) << "bin " << i << "," << j;
      }
  }
}

TEST(DenseVlad, VersionOneVocabularyIsRefusedWithTheReason) {
  try {
    Vocabulary::Parse("locforge-densevlad 1\nclusters 1 dim 128\n", "old.bin");
    FAIL() << "a version-1 vocabulary was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("train it again"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("old.bin"), std::string::npos) << e.what();
  }
}

TEST(DenseVlad, SimulatorQueriesRetrieveNearbyMapImages) {
  const std::string sim_plugin = LOCFORGE_SIMULATOR_PLUGIN_FILE;
  if (sim_plugin.empty()) GTEST_SKIP() << "simulator plugin not built";
  const fs::path tmp = locforge::testing::MakeTempDir("densevlad_sim");
  runtime::Registry registry;
  for (const char* f : {LOCFORGE_GLOBAL_PLUGIN_FILE, LOCFORGE_PAIRS_PLUGIN_FILE})
    ASSERT_TRUE(registry.LoadFile(f));
  ASSERT_TRUE(registry.LoadFile(sim_plugin));
  RunStage(registry, "source/simulator", {{"preset", "tiny"}, {"seed", "1"}, {"lidar", "false"}, {"duration_scale", "0.35"}}, {},
           tmp / "sim");
  const fs::path map = tmp / "sim", queries = tmp / "sim/validation";
  const runtime::InputArtifact map_images{"images", "kapture.dataset", map};
  RunStage(registry, "global/densevlad_vocabulary",
           {{"clusters", "32"}, {"sample_size", "20000"}, {"grid_step", "3"}}, {map_images}, tmp / "voc");
  const runtime::InputArtifact voc{"vocabulary", "densevlad.vocabulary", tmp / "voc"};
  RunStage(registry, "global/densevlad", {}, {map_images, voc}, tmp / "map_gf");
  RunStage(registry, "global/densevlad", {}, {{"images", "kapture.dataset", queries}, voc}, tmp / "query_gf");
  RunStage(registry, "pairs/retrieval", {{"topk", "1"}},
           {{"map_features", "kapture.global_features", tmp / "map_gf"},
            {"query_features", "kapture.global_features", tmp / "query_gf"}},
           tmp / "pairs");
  const auto map_centres = Centres(map), query_centres = Centres(queries);
  const auto pairs = ReadPairs(tmp / "pairs");
  ASSERT_EQ(pairs.size(), query_centres.size());
  std::vector<double> d;
  for (const auto& p : pairs) d.push_back((map_centres.at(p.map) - query_centres.at(p.query)).norm());
  std::sort(d.begin(), d.end());
  const double within3 = std::count_if(d.begin(), d.end(), [](double x) { return x < 3.0; }) / double(d.size());
  std::cout << pairs.size() << " queries: top-1 centre distance median " << d[d.size() / 2] << " m, "
            << 100 * within3 << " % within 3 m\n";
  EXPECT_GT(within3, 0.6);
  fs::remove_all(tmp);
}

TEST(RetrievalPlugin, DenseVladRunsDeterministically) {
  LOCFORGE_SHARED_PATH_OR_SKIP(shared, "data/kapture/virtual_gallery_tutorial");
  const fs::path tmp = locforge::testing::MakeTempDir("densevlad_det");
  runtime::Registry registry;
  for (const char* f : {LOCFORGE_GLOBAL_PLUGIN_FILE, LOCFORGE_PAIRS_PLUGIN_FILE})
    ASSERT_TRUE(testkit::CheckLoads(registry, f).ok());
  const runtime::InputArtifact map{"images", "kapture.dataset", shared / "query"};
  testkit::DeterminismCase c;
  c.stage_id = "global/densevlad_vocabulary";
  c.params = {{"clusters", "8"}, {"sample_size", "4000"}, {"max_image_size", "240"}, {"pca_dims", "2"}};
  c.inputs = {map};
  c.threads = 3;
  auto report = testkit::CheckDeterminism(registry, c);
  EXPECT_TRUE(report.ok()) << report.ToString();
  RunStage(registry, c.stage_id, c.params, c.inputs, tmp / "voc");
  c.stage_id = "global/densevlad";
  c.params = {};
  c.inputs = {map, {"vocabulary", "densevlad.vocabulary", tmp / "voc"}};
  report = testkit::CheckDeterminism(registry, c);
  EXPECT_TRUE(report.ok()) << report.ToString();
  fs::remove_all(tmp);
}

TEST(RetrievalPlugin, Conforms) {
  for (const char* f : {LOCFORGE_GLOBAL_PLUGIN_FILE, LOCFORGE_PAIRS_PLUGIN_FILE}) {
    const auto report = testkit::CheckPlugin(f);
    EXPECT_TRUE(report.ok()) << report.ToString();
  }
}

}  // namespace
}  // namespace locforge::retrieval

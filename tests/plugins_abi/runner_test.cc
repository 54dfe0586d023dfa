// The per-item runner: resume after failures, cancellation and torn journals,
// sharding, thread parallelism with identical outputs, serial stages; and the
// example stages end to end, including their input errors.
#include <gtest/gtest.h>

#include <atomic>
#include <set>

#include "locforge/error.h"
#include "locforge/testkit.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using locforge::runtime::Registry;
using lftest::StageRun;

const fs::path kExamples = LFTEST_EXAMPLES_PLUGIN;
const fs::path kTestPlugins = LFTEST_PLUGIN_DIR;

class Runner : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(registry_.LoadFile(kTestPlugins / "liblftest_items.so"));
    ASSERT_TRUE(registry_.LoadFile(kExamples));
    dir_ = locforge::testing::MakeTempDir("lfabi-runner");
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  StageRun Items(const fs::path& out, int count, int threads) {
    StageRun run{&registry_, "test/items", {{"count", std::to_string(count)}}, {}, {}};
    run.options.workspace = dir_;
    run.options.output_dir = out;
    run.options.threads = threads;
    return run;
  }
  static std::set<std::string> Processed(const StageRun& run) {
    std::set<std::string> out;
    for (const auto& l : run.LogsStartingWith("processed ")) out.insert(l.substr(10));
    return out;
  }
  Registry registry_;
  fs::path dir_;
};

TEST_F(Runner, FailedItemFailsTheRunAndARerunProcessesOnlyIt) {
  const fs::path out = dir_ / "out";
  std::ofstream(dir_ / "fail-item_007") << "";
  StageRun first = Items(out, 20, 4);
  try {
    first();
    FAIL() << "the failing item did not fail the run";
  } catch (const locforge::Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("test/items: 1 of 20 items failed: item 'item_007': planned failure of item_007"),
              std::string::npos) << m;
  }
  EXPECT_EQ(Processed(first).size(), 19u);  // the others went on
  EXPECT_FALSE(fs::exists(out / "summary.txt"));
  EXPECT_EQ(lftest::Lines(lftest::Slurp(out / ".items-done.0-of-1")).size(), 19u);
  // The failed item is listed with its reason, one line after the header.
  const auto failures = lftest::Lines(lftest::Slurp(out / "failures.txt"));
  ASSERT_EQ(failures.size(), 2u);
  EXPECT_EQ(failures[0], "# item, reason");
  EXPECT_EQ(failures[1], "item_007, planned failure of item_007");

  fs::remove(dir_ / "fail-item_007");
  StageRun second = Items(out, 20, 4);
  const auto result = second();
  EXPECT_TRUE(result.complete);
  EXPECT_EQ(result.items_total, 20u);
  EXPECT_EQ(result.items_resumed, 19u);
  EXPECT_EQ(result.items_processed, 1u);
  EXPECT_EQ(Processed(second), std::set<std::string>{"item_007"});
  EXPECT_EQ(lftest::Lines(lftest::Slurp(out / "summary.txt")).size(), 20u);
  EXPECT_FALSE(fs::exists(out / "failures.txt"));  // every item done: nothing left to list
}

TEST_F(Runner, TornJournalLineIsIgnoredAndRepaired) {
  const fs::path out = dir_ / "out";
  StageRun full = Items(out, 5, 2);
  ASSERT_TRUE(full().complete);
  // As if killed mid-write: two whole lines, then half of a third.
  std::ofstream(out / ".items-done.0-of-1", std::ios::trunc) << "item_001\nitem_002\nitem_0";
  StageRun run = Items(out, 5, 2);
  const auto result = run();
  EXPECT_TRUE(result.complete);
  EXPECT_EQ(result.items_resumed, 2u);
  EXPECT_EQ(Processed(run), (std::set<std::string>{"item_000", "item_003", "item_004"}));
  const auto lines = lftest::Lines(lftest::Slurp(out / ".items-done.0-of-1"));
  EXPECT_EQ(std::set<std::string>(lines.begin(), lines.end()),
            (std::set<std::string>{"item_000", "item_001", "item_002", "item_003", "item_004"}));
  EXPECT_EQ(lines.size(), 5u);
}

TEST_F(Runner, CancelStopsAndTheRestResumes) {
  const fs::path out = dir_ / "out";
  std::atomic<bool> cancel{false};
  StageRun first = Items(out, 30, 1);
  first.options.cancel = &cancel;
  first.options.progress = [&](uint64_t done, uint64_t, const std::string&) {
    if (done >= 5) cancel = true;
  };
  EXPECT_THROW(first(), locforge::Cancelled);
  const size_t done = Processed(first).size();
  EXPECT_EQ(done, 5u);
  StageRun second = Items(out, 30, 3);
  const auto result = second();
  EXPECT_TRUE(result.complete);
  EXPECT_EQ(result.items_resumed, done);
  EXPECT_EQ(result.items_processed, 30u - done);
}

TEST_F(Runner, ShardsProcessDisjointItemsAndFinalizeAfterAll) {
  const fs::path out = dir_ / "out";
  StageRun shard0 = Items(out, 40, 2);
  shard0.options.shard_count = 2;
  const auto r0 = shard0();
  EXPECT_FALSE(r0.complete);
  EXPECT_FALSE(fs::exists(out / "summary.txt"));
  StageRun shard1 = Items(out, 40, 2);
  shard1.options.shard_count = 2;
  shard1.options.shard_index = 1;
  const auto r1 = shard1();
  EXPECT_TRUE(r1.complete);
  EXPECT_TRUE(fs::exists(out / "summary.txt"));

  const auto p0 = Processed(shard0), p1 = Processed(shard1);
  EXPECT_GT(p0.size(), 5u);
  EXPECT_GT(p1.size(), 5u);
  EXPECT_EQ(p0.size() + p1.size(), 40u);
  EXPECT_EQ(r0.items_total, p0.size());
  EXPECT_EQ(r1.items_total, p1.size());
  for (const auto& item : p0) {
    EXPECT_EQ(p1.count(item), 0u) << item;
    EXPECT_EQ(locforge::runtime::ShardOfItem(item, 2), 0);
  }
  for (const auto& item : p1) EXPECT_EQ(locforge::runtime::ShardOfItem(item, 2), 1);
  EXPECT_TRUE(fs::exists(out / ".items-done.0-of-2"));
  EXPECT_TRUE(fs::exists(out / ".items-done.1-of-2"));

  // Same outputs as one unsharded run.
  StageRun whole = Items(dir_ / "whole", 40, 1);
  EXPECT_TRUE(whole().complete);
  const auto diff = locforge::testkit::CompareFolders(out, dir_ / "whole");
  EXPECT_TRUE(diff.ok()) << diff.ToString();

  // A later single-process run sees all items journaled by both shards.
  StageRun again = Items(out, 40, 1);
  const auto r = again();
  EXPECT_TRUE(r.complete);
  EXPECT_EQ(r.items_processed, 0u);
  EXPECT_EQ(r.items_resumed, 40u);
}

TEST_F(Runner, ThreadsRunItemsInParallelWithIdenticalOutputs) {
  StageRun parallel = Items(dir_ / "parallel", 40, 4);
  parallel.params.push_back({"sleep_ms", "5"});
  StageRun serial = Items(dir_ / "serial", 40, 1);
  serial.params.push_back({"sleep_ms", "1"});
  std::vector<uint64_t> seen;
  parallel.options.progress = [&](uint64_t done, uint64_t total, const std::string&) {
    EXPECT_EQ(total, 40u);
    seen.push_back(done);
  };
  EXPECT_TRUE(parallel().complete);
  EXPECT_TRUE(serial().complete);
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back(), 40u);
  EXPECT_TRUE(std::is_sorted(seen.begin(), seen.end()));
  const auto max_parallel = parallel.LogsStartingWith("max_active ");
  ASSERT_EQ(max_parallel.size(), 1u);
  EXPECT_GE(std::stoi(max_parallel[0].substr(11)), 2) << "items did not overlap";
  EXPECT_EQ(serial.LogsStartingWith("max_active "), std::vector<std::string>{"max_active 1"});
  const auto diff = locforge::testkit::CompareFolders(dir_ / "parallel", dir_ / "serial");
  EXPECT_TRUE(diff.ok()) << diff.ToString();
}

TEST_F(Runner, SerialStageIsNeverEnteredConcurrently) {
  StageRun run{&registry_, "test/serial_items", {{"count", "12"}, {"sleep_ms", "3"}}, {}, {}};
  run.options.output_dir = dir_ / "out";
  run.options.workspace = dir_;
  run.options.threads = 4;
  EXPECT_TRUE(run().complete);
  EXPECT_EQ(run.LogsStartingWith("max_active "), std::vector<std::string>{"max_active 1"});
}

TEST_F(Runner, DuplicateItemIdsAreRefused) {
  StageRun run = Items(dir_ / "out", 4, 2);
  run.params.push_back({"duplicate", "true"});
  try {
    run();
    FAIL() << "duplicates accepted";
  } catch (const locforge::Error& e) {
    EXPECT_NE(std::string(e.what()).find("emitted item 'item_000' twice"), std::string::npos)
        << e.what();
  }
}

TEST_F(Runner, InvalidShardIsRefused) {
  StageRun run = Items(dir_ / "out", 4, 1);
  run.options.shard_count = 2;
  run.options.shard_index = 2;
  EXPECT_THROW(run(), locforge::Error);
}

// ---- Example stages end to end -------------------------------------------

TEST_F(Runner, SyntheticImagesWriteAKaptureDataset) {
  const fs::path dataset = lftest::MakeSyntheticDataset(registry_, dir_, 4);
  const auto sensors = lftest::Lines(lftest::Slurp(dataset / "sensors" / "sensors.txt"));
  ASSERT_EQ(sensors.size(), 3u);
  EXPECT_EQ(sensors[0], "# kapture format: 1.1");
  EXPECT_EQ(sensors[2], "cam0, synthetic, camera, PINHOLE, 40, 30, 48, 48, 20, 15");
  const auto records = lftest::Lines(lftest::Slurp(dataset / "sensors" / "records_camera.txt"));
  ASSERT_EQ(records.size(), 6u);
  EXPECT_EQ(records[1], "# timestamp, device_id, image_path");
  EXPECT_EQ(records[5], "3, cam0, cam0/00003.png");
  for (int i = 0; i < 4; ++i) {
    const std::string png = lftest::Slurp(dataset / "sensors" / "records_data" / "cam0" /
                                          ("0000" + std::to_string(i) + ".png"));
    ASSERT_GT(png.size(), 8u);
    EXPECT_EQ(png.substr(1, 3), "PNG");
  }
  // Different seeds, different images; same seed, same bytes.
  const std::string a = lftest::Slurp(dataset / "sensors/records_data/cam0/00000.png");
  const std::string b = lftest::Slurp(dataset / "sensors/records_data/cam0/00001.png");
  EXPECT_NE(a, b);
  const fs::path again = lftest::MakeSyntheticDataset(registry_, dir_ / "again", 4);
  EXPECT_EQ(a, lftest::Slurp(again / "sensors/records_data/cam0/00000.png"));
}

TEST_F(Runner, ImageStatsMeasureEveryImage) {
  const fs::path dataset = lftest::MakeSyntheticDataset(registry_, dir_, 5, /*color=*/true);
  StageRun stats{&registry_, "example/image_stats", {{"bins", "10"}}, {}, {}};
  stats.options.output_dir = dir_ / "stats";
  stats.options.inputs = {{"images", "kapture.dataset", dataset}};
  stats.options.threads = 3;
  const auto result = stats();
  EXPECT_TRUE(result.complete);
  EXPECT_EQ(result.items_processed, 5u);
  const auto csv = lftest::Lines(lftest::Slurp(dir_ / "stats" / "stats.csv"));
  ASSERT_EQ(csv.size(), 6u);
  EXPECT_EQ(csv[0], "image,width,height,channels,mean,std,min,max");
  for (int i = 0; i < 5; ++i) {
    const std::string image = "cam0/0000" + std::to_string(i) + ".png";
    EXPECT_EQ(csv[i + 1].rfind(image + ",40,30,3,", 0), 0u) << csv[i + 1];
    std::vector<double> v;
    std::stringstream row(csv[i + 1].substr(image.size() + 1));
    for (std::string f; std::getline(row, f, ',');) v.push_back(std::stod(f));
    ASSERT_EQ(v.size(), 7u);
    const double mean = v[3], sd = v[4], lo = v[5], hi = v[6];
    EXPECT_LE(lo, mean);
    EXPECT_LE(mean, hi);
    EXPECT_GT(sd, 1.0);  // textured, not flat
    EXPECT_LE(sd, (hi - lo) / 2 + 1e-9);
    // The histogram counts every value once.
    const std::string json = lftest::Slurp(dir_ / "stats" / "stats" / (image + ".json"));
    const size_t open = json.find('['), close = json.find(']');
    std::stringstream bins(json.substr(open + 1, close - open - 1));
    uint64_t total = 0, count = 0;
    for (std::string f; std::getline(bins, f, ',');) total += std::stoull(f), ++count;
    EXPECT_EQ(count, 10u);
    EXPECT_EQ(total, 40u * 30u * 3u);
  }
}

TEST_F(Runner, ImageStatsNameTheRecordOfAMissingOrBrokenImage) {
  const fs::path dataset = lftest::MakeSyntheticDataset(registry_, dir_, 4);
  fs::remove(dataset / "sensors/records_data/cam0/00002.png");
  std::ofstream(dataset / "sensors/records_data/cam0/00003.png") << "not a png";
  const fs::path cut = dataset / "sensors/records_data/cam0/00001.png";
  fs::resize_file(cut, fs::file_size(cut) / 2);
  StageRun stats{&registry_, "example/image_stats", {}, {}, {}};
  stats.options.output_dir = dir_ / "stats";
  stats.options.inputs = {{"images", "kapture.dataset", dataset}};
  try {
    stats();
    FAIL() << "accepted";
  } catch (const locforge::InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("3 of 4 items failed"), std::string::npos) << m;
    EXPECT_NE(m.find("records_camera.txt:5: field 'image_path': image 'cam0/00002.png' not found"),
              std::string::npos) << m;
    EXPECT_NE(m.find("records_camera.txt:6: field 'image_path': unusable image 'cam0/00003.png'"),
              std::string::npos) << m;
    EXPECT_NE(m.find("not a PNG (no PNG signature)"), std::string::npos) << m;
    EXPECT_NE(m.find("records_camera.txt:4: field 'image_path': unusable image 'cam0/00001.png'"),
              std::string::npos) << m;
    EXPECT_NE(m.find("truncated PNG"), std::string::npos) << m;
  }
  EXPECT_FALSE(fs::exists(dir_ / "stats" / "stats.csv"));
}

TEST_F(Runner, ImageListImportsAFolderAndRefusesEscapes) {
  const fs::path dataset = lftest::MakeSyntheticDataset(registry_, dir_, 3);
  const fs::path root = dir_ / "photos";
  fs::create_directories(root / "sub");
  fs::copy_file(dataset / "sensors/records_data/cam0/00000.png", root / "b.png");
  fs::copy_file(dataset / "sensors/records_data/cam0/00001.png", root / "sub" / "a.PNG");
  std::ofstream(root / "notes.txt") << "ignored";
  StageRun import{&registry_, "source/image_list", {{"root", root.string()}}, {}, {}};
  import.options.output_dir = dir_ / "imported";
  ASSERT_TRUE(import().complete);
  const auto records =
      lftest::Lines(lftest::Slurp(dir_ / "imported/sensors/records_camera.txt"));
  ASSERT_EQ(records.size(), 4u);
  EXPECT_EQ(records[2], "0, cam0, b.png");
  EXPECT_EQ(records[3], "1, cam0, sub/a.PNG");
  EXPECT_EQ(lftest::Slurp(dir_ / "imported/sensors/records_data/sub/a.PNG"),
            lftest::Slurp(root / "sub" / "a.PNG"));
  const auto sensors = lftest::Lines(lftest::Slurp(dir_ / "imported/sensors/sensors.txt"));
  EXPECT_EQ(sensors.back(), "cam0, imported, camera, PINHOLE, 40, 30, 48, 48, 20, 15");

  // A link leading out of the root is refused, naming it.
  fs::create_symlink(dataset / "sensors/records_data/cam0/00002.png", root / "escape.png");
  StageRun escape{&registry_, "source/image_list", {{"root", root.string()}}, {}, {}};
  escape.options.output_dir = dir_ / "escaped";
  try {
    escape();
    FAIL() << "escape accepted";
  } catch (const locforge::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("escape.png"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("outside"), std::string::npos) << e.what();
  }
}

}  // namespace

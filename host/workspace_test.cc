// Cache key stability and sensitivity, node folders, links.
#include "workspace.h"

#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/params.h"

#include <gtest/gtest.h>

#include <fstream>
#include <thread>

#include "locforge/sha256.h"
#include "test_stages.h"
#include "testing.h"

namespace locforge::host {
namespace {

class CacheKeyTest : public ::testing::Test {
 protected:
  ResolvedNode Node(std::map<std::string, std::string> params) {
    ResolvedNode n;
    n.name = "imgs";
    n.stage = stages_.Find("source/images");
    n.params = {{"count", "8"}, {"verbose", "false"}, {"mode", "fast"}};
    for (const auto& [k, v] : params) n.params[k] = v;
    return n;
  }
  testing::FakeStages stages_;
};

TEST_F(CacheKeyTest, StableForTheSameInputs) {
  const std::string key = CacheKey(Node({}), {});
  EXPECT_EQ(key.size(), 64u);
  EXPECT_EQ(key, CacheKey(Node({}), {}));
  EXPECT_EQ(key, CacheKey(Node({{"mode", "fast"}}), {}));
}

TEST_F(CacheKeyTest, SensitiveToParamsPluginVersionAndInputs) {
  const std::string key = CacheKey(Node({}), {});
  EXPECT_NE(key, CacheKey(Node({{"count", "9"}}), {}));
  EXPECT_NE(key, CacheKey(Node({{"mode", "slow"}}), {}));
  // LF_PARAM_NO_CACHE_KEY parameters do not change results, nor the key.
  EXPECT_EQ(key, CacheKey(Node({{"verbose", "true"}}), {}));
  stages_.plugin_info().version = "1.0.1";
  EXPECT_NE(key, CacheKey(Node({}), {}));
  stages_.plugin_info().version = "1.0.0";
  stages_.plugin_info().sdk_version = "0.2.0";
  EXPECT_NE(key, CacheKey(Node({}), {}));
  stages_.plugin_info().sdk_version = "0.1.0";
  EXPECT_EQ(key, CacheKey(Node({}), {}));

  ResolvedNode feats;
  feats.name = "feats";
  feats.stage = stages_.Find("features/sift");
  feats.params = {{"count", "8"}, {"scales", "1"}};
  feats.inputs = {{"images", "kapture.dataset", "imgs", "images"}};
  const std::string a = CacheKey(feats, {{"imgs", key}});
  EXPECT_EQ(a, CacheKey(feats, {{"imgs", key}}));
  EXPECT_NE(a, CacheKey(feats, {{"imgs", CacheKey(Node({{"count", "9"}}), {})}}));
}

TEST_F(CacheKeyTest, PathParamsEnterByContentStamp) {
  const fs::path dir = locforge::testing::MakeTempDir("lf-key");
  fs::create_directories(dir / "data" / "sub");
  std::ofstream(dir / "data" / "a.txt") << "one";
  ResolvedNode n;
  n.name = "folder";
  n.stage = stages_.Find("source/folder");
  n.params = {{"root", (dir / "data").string()}};
  const std::string k1 = CacheKey(n, {});
  EXPECT_EQ(k1, CacheKey(n, {}));
  std::ofstream(dir / "data" / "sub" / "b.txt") << "two";  // depth 2: part of the stamp
  const std::string k2 = CacheKey(n, {});
  EXPECT_NE(k1, k2);
  std::ofstream(dir / "data" / "a.txt") << "longer content";  // size changes
  EXPECT_NE(k2, CacheKey(n, {}));
  // A change deep inside the folder (as in a kapture's validation/sensors/) counts too.
  fs::create_directories(dir / "data" / "validation" / "sensors" / "deeper");
  const std::string deep = (dir / "data" / "validation" / "sensors" / "deeper" / "t.txt").string();
  std::ofstream(deep) << "0, cam, 1, 0, 0, 0, 0, 0, 0";
  const std::string k3 = CacheKey(n, {});
  EXPECT_EQ(k3, CacheKey(n, {}));  // stable while nothing changes
  std::ofstream(deep) << "0, cam, 1, 0, 0, 0, 0, 0, 0.5";
  EXPECT_NE(k3, CacheKey(n, {}));
  EXPECT_NE(PathStamp(dir / "data").find(" dir 7 entries sha256:"), std::string::npos)
      << PathStamp(dir / "data");
  // A symlink cycle ends at the depth bound instead of looping.
  fs::create_directory_symlink(dir / "data", dir / "data" / "sub" / "loop");
  EXPECT_NE(PathStamp(dir / "data").find(" sha256:"), std::string::npos);
  EXPECT_NE(PathStamp(dir / "nothing").find(" missing"), std::string::npos);
  fs::remove_all(dir);
}

TEST(WorkspaceTest, FoldersLinksAndPublish) {
  const fs::path root = locforge::testing::MakeTempDir("lf-ws");
  Workspace ws(root / "ws");
  const std::string key(64, 'a');
  const fs::path dir = ws.NodeDir("stats", key);
  EXPECT_EQ(dir, root / "ws" / "cache" / "stats-aaaaaaaaaaaaaaaa");
  EXPECT_FALSE(Workspace::IsComplete(dir));
  fs::path partial = dir;
  partial += ".partial-1";
  fs::create_directories(partial);
  std::ofstream(partial / "out.txt") << "result";
  Publish(partial, dir, "{}\n");
  EXPECT_TRUE(Workspace::IsComplete(dir));
  EXPECT_FALSE(fs::exists(partial));
  ws.Link("", "stats", dir);
  EXPECT_EQ(fs::read_symlink(ws.LinkPath("", "stats")),
            fs::path("../cache/stats-aaaaaaaaaaaaaaaa"));
  EXPECT_TRUE(fs::exists(ws.LinkPath("", "stats") / "out.txt"));
  ws.Link("bins=8", "stats", dir);
  EXPECT_EQ(ws.LinkPath("bins=8", "stats"),
            root / "ws" / "variants" / "bins=8" / "nodes" / "stats");
  EXPECT_TRUE(fs::exists(ws.LinkPath("bins=8", "stats") / "out.txt"));
  // Publishing over a complete folder (--force) replaces it.
  fs::create_directories(partial);
  std::ofstream(partial / "new.txt") << "again";
  Publish(partial, dir, "{}\n");
  EXPECT_TRUE(fs::exists(dir / "new.txt"));
  EXPECT_FALSE(fs::exists(dir / "out.txt"));
  fs::remove_all(root);
}

TEST_F(CacheKeyTest, AStageVersionKeysItsResultsInsteadOfThePluginVersion) {
  ResolvedNode n;
  n.name = "icp";
  n.stage = stages_.Find("registration/fake_icp");  // its own version 2.0.0
  n.params = {{"iterations", "10"}, {"mode", "fast"}};
  const std::string key = CacheKey(n, {});
  EXPECT_NE(CacheKeyText(n, {}).find("stage_version 2.0.0"), std::string::npos);
  // The plugin's version no longer matters: its other stages can move on.
  stages_.plugin_info().version = "9.9.9";
  EXPECT_EQ(key, CacheKey(n, {}));
  stages_.plugin_info().version = "1.0.0";
  stages_.Entry("registration/fake_icp").version = "2.0.1";
  EXPECT_NE(key, CacheKey(n, {}));
  stages_.Entry("registration/fake_icp").version = "2.0.0";
}

TEST(WorkspaceTest, NodeFolderProtocol) {
  const fs::path root = locforge::testing::MakeTempDir("lf-ws-protocol");
  Workspace ws(root / "ws");
  const fs::path dir = ws.NodeDir("feats", std::string(64, 'b'));
  EXPECT_EQ(Workspace::PartialDir(dir, true), root / "ws" / "cache" / "feats-bbbbbbbbbbbbbbbb.partial");
  const fs::path mine = Workspace::PartialDir(dir, false);
  EXPECT_EQ(mine.filename().string().rfind("feats-bbbbbbbbbbbbbbbb.partial-", 0), 0u);
  EXPECT_EQ(ws.LockFile(dir, ".lock"), root / "ws" / "locks" / "feats-bbbbbbbbbbbbbbbb.lock");
  // Whole-stage partial folders left by a dead process go; the per-item one stays.
  fs::path stale = dir;
  stale += ".partial-999999";
  fs::create_directories(stale);
  fs::create_directories(Workspace::PartialDir(dir, true));
  Workspace::RemoveStalePartials(dir);
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(Workspace::PartialDir(dir, true)));
  fs::remove_all(root);
}

TEST(WorkspaceTest, ManifestRoundTripsThroughAJsonReader) {
  const fs::path root = locforge::testing::MakeTempDir("lf-ws-manifest");
  Manifest m;
  m.stage = "features/sift";
  m.plugin = "features";
  m.plugin_version = "1.0.0";
  m.stage_version = "1.1.0";
  m.plugin_file = "/p/libfeatures.so";
  m.key = std::string(64, 'c');
  // Values with quotes, backslashes, list and component separators.
  m.params = {{"type", "a \"quoted\" \\ name"},
              {"scales", JoinList({"1", "0.5"})},
              {"backend", "registration/gicp" + std::string(1, LF_COMPONENT_SEPARATOR) + "voxel_size=0.2"},
              {"items", "\"items\": 7"}};  // a value that fooled a search for "items"
  m.inputs = {{"images", "kapture.dataset", "/w/cache/images-0123"}};
  m.finished = "2026-12-01T23:00:00Z";
  m.items = 42;
  m.seconds = 1.5;
  m.cpu_seconds = 2.25;
  m.peak_rss_bytes = 123456789;
  m.output_bytes = 987654321012;
  m.shards = 3;
  m.started = "2026-12-01T22:59:00Z";
  fs::create_directories(root / "node");
  WriteFileAtomic(root / "node" / kCompleteMarker, FormatManifest(m));
  const Manifest back = ReadManifest(root / "node");
  EXPECT_EQ(back.stage, m.stage);
  EXPECT_EQ(back.stage_version, "1.1.0");
  EXPECT_EQ(back.key, m.key);
  EXPECT_EQ(back.params, m.params);
  ASSERT_EQ(back.inputs.size(), 1u);
  EXPECT_EQ(back.inputs[0].path, "/w/cache/images-0123");
  EXPECT_EQ(back.items, 42u);
  EXPECT_DOUBLE_EQ(back.seconds, 1.5);
  EXPECT_DOUBLE_EQ(back.cpu_seconds, 2.25);
  EXPECT_EQ(back.peak_rss_bytes, 123456789u);
  EXPECT_EQ(back.output_bytes, 987654321012u);
  EXPECT_EQ(back.shards, 3);
  EXPECT_EQ(back.started, m.started);
  // A wrong type names the field.
  WriteFileAtomic(root / "node" / kCompleteMarker, "{\"stage\": \"a/b\",\n \"cpu_seconds\": \"x\"}\n");
  try {
    ReadManifest(root / "node");
    FAIL() << "a text cpu_seconds accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cpu_seconds"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(":2"), std::string::npos) << e.what();
  }
  // Not JSON: an error naming the file, not a crash or a silent 0.
  WriteFileAtomic(root / "node" / kCompleteMarker, "{\"items\": [1,\n");
  try {
    ReadManifest(root / "node");
    FAIL() << "malformed manifest accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(kCompleteMarker), std::string::npos) << e.what();
  }
  fs::remove_all(root);
}

TEST(ShardRecords, WrittenReadAndMatchedToTheShardCount) {
  const fs::path dir = locforge::testing::MakeTempDir("lf-shard-records");
  ShardRecord r;
  r.index = 2;
  r.count = 3;
  r.items = 17;
  r.seconds = 4.5;
  r.cpu_seconds = 8.25;
  r.peak_rss_bytes = 3u << 30;
  r.host = "node\"7";
  r.started = "2026-12-01T22:00:00Z";
  r.finished = "2026-12-01T22:00:05Z";
  WriteShardRecord(dir, r);
  EXPECT_TRUE(fs::exists(dir / ".shard-done.2-of-3"));
  auto back = ReadShardRecords(dir, 3);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].index, 2);
  EXPECT_EQ(back[0].items, 17u);
  EXPECT_DOUBLE_EQ(back[0].cpu_seconds, 8.25);
  EXPECT_EQ(back[0].peak_rss_bytes, 3ull << 30);
  EXPECT_EQ(back[0].host, "node\"7");
  EXPECT_TRUE(ReadShardRecords(dir, 4).empty());  // another shard count: not these shards
  // A torn record counts as not done (the shard is submitted again).
  WriteFileAtomic(dir / ".shard-done.0-of-3", "{\"index\": 0, \"items\": ");
  EXPECT_EQ(ReadShardRecords(dir, 3).size(), 1u);
  fs::remove_all(dir);
}

TEST(OutputBytes, CountsOutputsNotBookkeepingNorLinks) {
  const fs::path dir = locforge::testing::MakeTempDir("lf-output-bytes");
  WriteFileAtomic(dir / "a.txt", std::string(1000, 'a'));
  fs::create_directories(dir / "sub/deeper");
  WriteFileAtomic(dir / "sub/deeper/b.bin", std::string(234, 'b'));
  WriteFileAtomic(dir / kCompleteMarker, std::string(50, 'm'));
  WriteFileAtomic(dir / ".items-done.0-of-1", "x\n");
  WriteFileAtomic(dir / ".shard-done.0-of-2", "{}");
  fs::create_symlink(dir / "a.txt", dir / "link.txt");  // the owner's file, not this node's
  EXPECT_EQ(OutputBytes(dir), 1234u);
  EXPECT_TRUE(IsProtocolFile(".items-done.3-of-4"));
  EXPECT_FALSE(IsProtocolFile("items-done.txt"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace locforge::host

// The test kit on the examples plugin (found in the build's plugin folder):
// it conforms, its stages are deterministic across thread counts; and the
// folder comparison catches what it should.
#include "locforge/testkit.h"

#include <gtest/gtest.h>

#include <fstream>

#include "testing.h"

namespace locforge::testkit {
namespace {

fs::path ExamplesPlugin() {
  for (const auto& dir : runtime::Registry::DefaultSearchPath())
    if (fs::exists(dir / "liblocforge_examples.so")) return dir / "liblocforge_examples.so";
  return {};
}

#define EXAMPLES_OR_SKIP(var)                                                           \
  const fs::path var = ExamplesPlugin();                                                \
  if (var.empty()) GTEST_SKIP() << "examples plugin not built (needs OpenCV)";

TEST(TestKit, ExamplesPluginConforms) {
  EXAMPLES_OR_SKIP(plugin);
  const Report report = CheckPlugin(plugin);
  EXPECT_TRUE(report.ok()) << report.ToString();
}

TEST(TestKit, ExampleStagesAreDeterministic) {
  EXAMPLES_OR_SKIP(plugin);
  runtime::Registry registry;
  ASSERT_TRUE(registry.LoadFile(plugin));
  const fs::path scratch = testing::MakeTempDir("lftestkit");
  DeterminismCase source;
  source.stage_id = "source/synthetic_images";
  source.params = {{"count", "6"}, {"width", "48"}, {"height", "32"}, {"color", "true"}};
  source.scratch = scratch / "source";
  const Report a = CheckDeterminism(registry, source);
  ASSERT_TRUE(a.ok()) << a.ToString();

  DeterminismCase stats;
  stats.stage_id = "example/image_stats";
  stats.params = {{"bins", "32"}};
  stats.inputs = {{"images", "kapture.dataset", scratch / "source" / "output1"}};
  stats.threads = 3;
  const Report b = CheckDeterminism(registry, stats);
  EXPECT_TRUE(b.ok()) << b.ToString();
  fs::remove_all(scratch);
}

TEST(TestKit, DeterminismReportsAFailingRun) {
  EXAMPLES_OR_SKIP(plugin);
  runtime::Registry registry;
  ASSERT_TRUE(registry.LoadFile(plugin));
  DeterminismCase stats;
  stats.stage_id = "example/image_stats";
  stats.inputs = {{"images", "kapture.dataset", "/nonexistent/dataset"}};
  const Report r = CheckDeterminism(registry, stats);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.failures[0].find("records_camera.txt"), std::string::npos) << r.ToString();
  DeterminismCase unknown;
  unknown.stage_id = "example/nope";
  EXPECT_FALSE(CheckDeterminism(registry, unknown).ok());
}

TEST(TestKit, CompareFoldersFindsEveryDifference) {
  const fs::path a = testing::MakeTempDir("lftestkit-a"), b = testing::MakeTempDir("lftestkit-b");
  fs::create_directories(a / "sub");
  fs::create_directories(b / "sub");
  std::ofstream(a / "same.txt") << "same";
  std::ofstream(b / "same.txt") << "same";
  std::ofstream(a / "sub" / "differs.bin") << "abcdef";
  std::ofstream(b / "sub" / "differs.bin") << "abcXef";
  std::ofstream(a / "only_a.txt") << "a";
  std::ofstream(b / ".items-done.0-of-1") << "ignored\n";
  std::ofstream(b / ".x.tmp-1-2") << "leftover";
  const Report r = CompareFolders(a, b);
  const std::string text = r.ToString();
  EXPECT_EQ(r.failures.size(), 4u) << text;
  EXPECT_NE(text.find("sub/differs.bin: contents differ (sizes 6 and 6, first difference at byte 3)"),
            std::string::npos) << text;
  EXPECT_NE(text.find("only_a.txt: written by the first run only"), std::string::npos) << text;
  EXPECT_NE(text.find("leftover temp file .x.tmp-1-2"), std::string::npos) << text;
  EXPECT_NE(text.find(".x.tmp-1-2: written by the second run only"), std::string::npos) << text;
  EXPECT_EQ(text.find("same.txt"), std::string::npos) << text;
  EXPECT_TRUE(CompareFolders(a, a).ok());
  fs::remove_all(a);
  fs::remove_all(b);
}

}  // namespace
}  // namespace locforge::testkit

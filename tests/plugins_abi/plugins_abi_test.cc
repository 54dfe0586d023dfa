// Broken plugins are refused with a message naming the file and the reason,
// without crashing, and the good plugin beside them still loads and runs.
// Also: duplicates, the search path, exceptions escaping plugin code,
// components created from inside a run, and the test kit's verdicts.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdlib>

#include "locforge/error.h"
#include "locforge/testkit.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using locforge::runtime::Registry;
using lftest::StageRun;

const fs::path kExamples = LFTEST_EXAMPLES_PLUGIN;
const fs::path kBroken = LFTEST_BROKEN_DIR;
const fs::path kTestPlugins = LFTEST_PLUGIN_DIR;

fs::path BrokenLib(const std::string& name) { return kBroken / name / ("lib" + name + ".so"); }

// The examples plugin, loaded from `dir`, generates a dataset and measures it.
void ExpectExamplesWork(const Registry& registry, const fs::path& dir) {
  ASSERT_NE(registry.Find("source/synthetic_images"), nullptr);
  ASSERT_NE(registry.Find("example/image_stats"), nullptr);
  EXPECT_EQ(registry.Find("example/image_stats")->plugin->file.parent_path(), fs::canonical(dir));
  const fs::path dataset = lftest::MakeSyntheticDataset(registry, dir, 3);
  StageRun stats{&registry, "example/image_stats", {{"bins", "8"}}, {}, {}};
  stats.options.workspace = dir;
  stats.options.output_dir = dir / "stats";
  stats.options.inputs = {{"images", "kapture.dataset", dataset}};
  stats.options.threads = 2;
  const auto result = stats();
  EXPECT_TRUE(result.complete);
  EXPECT_EQ(result.items_processed, 3u);
  EXPECT_EQ(lftest::Lines(lftest::Slurp(dir / "stats" / "stats.csv")).size(), 4u);
}

struct BrokenCase {
  std::string name;    // broken/<name>/lib<name>.so, or made at test time
  std::string reason;  // expected in the problem message
};

void PrintTo(const BrokenCase& c, std::ostream* os) { *os << c.name; }

class BrokenPlugin : public ::testing::TestWithParam<BrokenCase> {};

TEST_P(BrokenPlugin, IsRefusedWithReasonAndGoodPluginStillRuns) {
  const BrokenCase& c = GetParam();
  const fs::path dir = locforge::testing::MakeTempDir("lfabi-" + c.name);
  const fs::path lib = dir / ("lib" + c.name + ".so");
  if (c.name == "truncated") {  // a real plugin cut short, as by an interrupted copy
    fs::copy_file(kExamples, lib);
    fs::resize_file(lib, fs::file_size(lib) / 3);
  } else if (c.name == "junk") {
    std::ofstream(lib) << "this is not a shared library\n";
  } else {
    fs::copy_file(BrokenLib(c.name), lib);
  }
  fs::copy_file(kExamples, dir / "liblocforge_examples.so");

  Registry registry;
  registry.LoadFolder(dir);
  ASSERT_EQ(registry.problems().size(), 1u);
  const auto& problem = registry.problems().front();
  EXPECT_EQ(problem.file.filename(), lib.filename());
  EXPECT_EQ(problem.message.rfind(lib.filename().string() + ": ", 0), 0u) << problem.message;
  EXPECT_NE(problem.message.find(c.reason), std::string::npos) << problem.message;
  EXPECT_EQ(problem.message.find('\n'), std::string::npos) << "one line: " << problem.message;
  ASSERT_EQ(registry.plugins().size(), 1u);
  ExpectExamplesWork(registry, dir);
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(
    Cases, BrokenPlugin,
    ::testing::Values(
        BrokenCase{"abi_v2", "plugin ABI version 2, host supports 1; rebuild the plugin against "
                             "this locforge SDK"},
        BrokenCase{"small_struct", "LfPluginInfo struct_size 8 is smaller than this host's"},
        BrokenCase{"small_stage_struct", "LfStageInfo struct_size 24 is smaller than this host's"},
        BrokenCase{"no_entry", "no locforge_plugin_entry symbol; not a locforge plugin"},
        BrokenCase{"unresolved", "undefined symbol: lftest_missing_function"},
        BrokenCase{"entry_throws", "threw a C++ exception (static metadata failed to build)"},
        BrokenCase{"entry_null", "entry point returned NULL"},
        BrokenCase{"null_name", "name NULL must be non-empty"},
        BrokenCase{"bad_default", "parameter 'iterations': invalid default value: value 42 is out "
                                  "of range [0, 10]"},
        BrokenCase{"derived_default", "parameter 'iterations': LF_PARAM_DERIVED needs the default \"\""},
        BrokenCase{"missing_run", "required function 'run' is NULL"},
        BrokenCase{"truncated", "cannot load shared library"},
        BrokenCase{"junk", "cannot load shared library"}),
    [](const ::testing::TestParamInfo<BrokenCase>& info) { return info.param.name; });

TEST(Registry, DuplicateStagesNameBothFilesAndKeepTheFirst) {
  const fs::path dir = locforge::testing::MakeTempDir("lfabi-dup");
  fs::copy_file(kExamples, dir / "liba.so");
  fs::copy_file(kExamples, dir / "libb.so");
  Registry registry;
  registry.LoadFolder(dir);
  EXPECT_TRUE(registry.problems().empty());
  EXPECT_EQ(registry.plugins().size(), 2u);
  ASSERT_EQ(registry.duplicates().size(), registry.Stages().size());
  for (const auto& d : registry.duplicates()) {
    EXPECT_NE(d.find((fs::canonical(dir) / "liba.so").string()), std::string::npos) << d;
    EXPECT_NE(d.find((fs::canonical(dir) / "libb.so").string()), std::string::npos) << d;
  }
  for (const auto* s : registry.Stages()) EXPECT_EQ(s->plugin->file.filename(), "liba.so");
  // Loading the same file again is a no-op, not a duplicate.
  EXPECT_TRUE(registry.LoadFile(dir / "liba.so"));
  EXPECT_EQ(registry.duplicates().size(), registry.Stages().size());
  ExpectExamplesWork(registry, dir);
  fs::remove_all(dir);
}

TEST(Registry, LoadsPluginsWithLargerFutureStructs) {
  Registry registry;
  ASSERT_TRUE(registry.LoadFile(BrokenLib("future_structs")))
      << (registry.problems().empty() ? "" : registry.problems()[0].message);
  EXPECT_EQ(registry.StageIds(), (std::vector<std::string>{"broken/future_one", "broken/future_two"}));
  for (const auto* stage : registry.Stages()) {
    ASSERT_EQ(stage->params.size(), 2u);
    EXPECT_EQ(stage->params[0].name, "alpha");
    EXPECT_EQ(stage->params[1].name, "beta");
    EXPECT_EQ(stage->params[1].default_value, "2");
    EXPECT_EQ(stage->outputs.size(), 1u);
  }
  const auto* two = registry.Find("broken/future_two");
  const auto resolved = locforge::runtime::CheckStageParams(*two, {{"beta", "5"}});
  EXPECT_EQ(resolved.at("alpha"), "1");
  EXPECT_EQ(resolved.at("beta"), "5");
}

TEST(Registry, AppendedFieldsAreReadOnlyWhenTheStructHoldsThem) {
  Registry registry;
  ASSERT_TRUE(registry.LoadFile(BrokenLib("v1_structs")))
      << (registry.problems().empty() ? "" : registry.problems().front().message);
  const auto* stage = registry.Find("broken/v1_stage");
  ASSERT_NE(stage, nullptr);
  // No version field: the plugin's version keys the stage's results.
  EXPECT_FALSE(stage->own_version);
  EXPECT_EQ(stage->version, "0.0.1");
  EXPECT_EQ(stage->params.at(0).component_interface, "");
}

TEST(Registry, StagesRegisteredInTheirFilesBelongToTheirOwnPlugin) {
  Registry registry;
  ASSERT_TRUE(registry.LoadFile(kTestPlugins / "liblftest_registered.so"));
  ASSERT_TRUE(registry.LoadFile(kTestPlugins / "liblftest_registered_other.so"));
  EXPECT_TRUE(registry.problems().empty());
  EXPECT_TRUE(registry.duplicates().empty());
  EXPECT_EQ(registry.StageIds(),
            (std::vector<std::string>{"test/registered_a", "test/registered_b", "test/registered_c"}));
  EXPECT_EQ(registry.Find("test/registered_a")->plugin->file.filename(), "liblftest_registered.so");
  EXPECT_EQ(registry.Find("test/registered_b")->plugin->file.filename(), "liblftest_registered.so");
  EXPECT_EQ(registry.Find("test/registered_c")->plugin->file.filename(), "liblftest_registered_other.so");
}

TEST(Registry, StageVersionsOverrideThePluginVersion) {
  Registry registry;
  ASSERT_TRUE(registry.LoadFile(kTestPlugins / "liblftest_components.so"));
  const auto* kabsch = registry.Find("registration/kabsch_test");
  ASSERT_NE(kabsch, nullptr);
  EXPECT_TRUE(kabsch->own_version);
  EXPECT_EQ(kabsch->version, "2.0.0");
  const auto* check = registry.Find("test/align_check");
  ASSERT_NE(check, nullptr);
  EXPECT_FALSE(check->own_version);
  EXPECT_EQ(check->version, "1.0.0");
  // A typed component parameter carries the interface it needs.
  ASSERT_EQ(check->params.at(0).name, "backend");
  EXPECT_EQ(check->params.at(0).type, LF_PARAM_COMPONENT);
  EXPECT_EQ(check->params.at(0).component_interface, LF_REGISTRATION_INTERFACE);
}

TEST(Registry, MetadataIsReadIntoDecls) {
  Registry registry;
  ASSERT_TRUE(registry.LoadFile(kExamples));
  const auto* stats = registry.Find("example/image_stats");
  ASSERT_NE(stats, nullptr);
  EXPECT_TRUE(stats->per_item());
  ASSERT_EQ(stats->params.size(), 1u);
  EXPECT_EQ(stats->params[0].name, "bins");
  EXPECT_EQ(stats->params[0].default_value, "16");
  EXPECT_TRUE(stats->params[0].has_min && stats->params[0].has_max);
  ASSERT_EQ(stats->inputs.size(), 1u);
  EXPECT_EQ(stats->inputs[0].artifact_type, "kapture.dataset");
  ASSERT_EQ(stats->outputs.size(), 1u);
  EXPECT_EQ(stats->outputs[0].artifact_type, "report");
  const auto ids = registry.StageIds();
  EXPECT_EQ(ids, (std::vector<std::string>{"example/image_stats", "source/image_list",
                                           "source/synthetic_images"}));
  // Parameter refusals name the stage and the parameter.
  try {
    locforge::runtime::CheckStageParams(*stats, {{"bins", "0"}});
    FAIL() << "bins=0 accepted";
  } catch (const locforge::ParamError& e) {
    EXPECT_NE(std::string(e.what()).find("example/image_stats: parameter 'bins'"), std::string::npos)
        << e.what();
  }
  try {
    locforge::runtime::CheckStageParams(*stats, {{"binz", "3"}});
    FAIL() << "unknown parameter accepted";
  } catch (const locforge::ParamError& e) {
    EXPECT_NE(std::string(e.what()).find("did you mean 'bins'"), std::string::npos) << e.what();
  }
}

TEST(Registry, SearchPathDedupesSkipsMissingAndCanBeIsolated) {
  const fs::path a = locforge::testing::MakeTempDir("lfabi-path-a");
  const fs::path b = locforge::testing::MakeTempDir("lfabi-path-b");
  const std::string env = a.string() + ":/nonexistent/locforge:" + b.string() + ":" + a.string();
  setenv("LOCFORGE_PLUGIN_PATH", env.c_str(), 1);
  setenv("LOCFORGE_NO_DEFAULT_PLUGINS", "1", 1);
  EXPECT_EQ(Registry::DefaultSearchPath(), (std::vector<fs::path>{fs::canonical(a), fs::canonical(b)}));
  unsetenv("LOCFORGE_NO_DEFAULT_PLUGINS");
  const auto all = Registry::DefaultSearchPath();
  ASSERT_GE(all.size(), 2u);
  EXPECT_EQ(all[all.size() - 2], fs::canonical(a));
  EXPECT_EQ(all.back(), fs::canonical(b));
  setenv("LOCFORGE_NO_DEFAULT_PLUGINS", "1", 1);
  unsetenv("LOCFORGE_PLUGIN_PATH");
  EXPECT_TRUE(Registry::DefaultSearchPath().empty());
  fs::remove_all(a);
  fs::remove_all(b);
}

TEST(PluginExceptions, EscapingExceptionsBecomeErrors) {
  Registry registry;
  ASSERT_TRUE(registry.LoadFile(BrokenLib("throwing_raw")));
  ASSERT_TRUE(registry.LoadFile(kTestPlugins / "liblftest_throwing_adapter.so"));
  EXPECT_TRUE(registry.problems().empty());
  const fs::path dir = locforge::testing::MakeTempDir("lfabi-throw");

  const auto* check = registry.Find("broken/throwing_check");
  ASSERT_NE(check, nullptr);
  try {
    locforge::runtime::CheckStageParams(*check, {});
    FAIL() << "no error";
  } catch (const locforge::ParamError& e) {
    EXPECT_NE(std::string(e.what()).find("broken/throwing_check"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("check_params exploded"), std::string::npos) << e.what();
  }
  for (const auto& [id, what] : std::vector<std::pair<std::string, std::string>>{
           {"broken/throwing_create", "factory exploded"},
           {"test/throwing_create", "constructor refused to build"}}) {
    const auto* stage = registry.Find(id);
    ASSERT_NE(stage, nullptr) << id;
    try {
      locforge::runtime::StageInstance instance(*stage, {});
      FAIL() << id << ": created";
    } catch (const locforge::Error& e) {
      EXPECT_NE(std::string(e.what()).find(id + ": cannot create the stage"), std::string::npos)
          << e.what();
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  }
  StageRun run{&registry, "broken/throwing_run", {}, {}, {}};
  run.options.output_dir = dir / "out";
  try {
    run();
    FAIL() << "no error";
  } catch (const locforge::Error& e) {
    EXPECT_NE(std::string(e.what()).find("run exploded"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

class Components : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(registry_.LoadFile(kTestPlugins / "liblftest_components.so"));
    locforge::runtime::SetComponentRegistry(&registry_);
    dir_ = locforge::testing::MakeTempDir("lfabi-components");
  }
  void TearDown() override {
    locforge::runtime::SetComponentRegistry(nullptr);
    fs::remove_all(dir_);
  }
  Registry registry_;
  fs::path dir_;
};

TEST_F(Components, StageCreatesAComponentAndRecoversAKnownTransform) {
  const double rx = 0.4, ry = -0.25, rz = 1.1;
  StageRun run{&registry_, "test/align_check",
          {{"rotation", locforge::JoinList({"0.4", "-0.25", "1.1"})},
           {"translation", locforge::JoinList({"3", "-1.5", "0.25"})},
           {"points", "500"}},
          {}, {}};
  run.options.output_dir = dir_ / "out";
  run.options.threads = 2;
  ASSERT_TRUE(run().complete);
  const auto lines = lftest::Lines(lftest::Slurp(dir_ / "out" / "transform.txt"));
  ASSERT_EQ(lines.size(), 6u);
  Eigen::Matrix4d recovered;
  for (int r = 0; r < 4; ++r) {
    std::istringstream row(lines[r]);
    for (int c = 0; c < 4; ++c) row >> recovered(r, c);
  }
  Eigen::Matrix4d expected = Eigen::Matrix4d::Identity();
  expected.topLeftCorner<3, 3>() = (Eigen::AngleAxisd(rz, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(ry, Eigen::Vector3d::UnitY()) *
                                    Eigen::AngleAxisd(rx, Eigen::Vector3d::UnitX()))
                                       .toRotationMatrix();
  expected.topRightCorner<3, 1>() = Eigen::Vector3d(3, -1.5, 0.25);
  // Points are floats: agreement to float precision of metre-scale coordinates.
  EXPECT_LT((recovered - expected).cwiseAbs().maxCoeff(), 1e-5) << recovered;
  EXPECT_EQ(lines[4].rfind("final_error ", 0), 0u);
  EXPECT_LT(std::stod(lines[4].substr(12)), 1e-5);
  EXPECT_EQ(lines[5], "inliers 500");
}

TEST_F(Components, HostCanUseTheComponentTableDirectly) {
  const auto* stage = registry_.Find("registration/kabsch_test");
  ASSERT_NE(stage, nullptr);
  EXPECT_TRUE(stage->is_component());
  EXPECT_FALSE(stage->runnable());
  locforge::runtime::StageInstance instance(*stage, locforge::runtime::CheckStageParams(*stage, {}));
  const auto* table = static_cast<const LfRegistrationInterface*>(instance.Component());
  ASSERT_NE(table, nullptr);
  // Target = source shifted by (1, 2, 3): a pure translation.
  const std::vector<float> src = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::vector<float> tgt = src;
  for (size_t i = 0; i < tgt.size(); ++i) tgt[i] += static_cast<float>(i % 3 + 1);
  LfPointCloudView s{sizeof(LfPointCloudView), 4, src.data(), 12, nullptr, 0, nullptr, 0};
  LfPointCloudView t = s;
  t.xyz = tgt.data();
  const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  LfRegistrationResult result{};
  LfError err{};
  ASSERT_EQ(table->align(instance.raw(), &s, &t, identity, 1, &result, &err), LF_OK) << err.message;
  EXPECT_NEAR(result.T_target_source[3], 1, 1e-9);
  EXPECT_NEAR(result.T_target_source[7], 2, 1e-9);
  EXPECT_NEAR(result.T_target_source[11], 3, 1e-9);
  EXPECT_NEAR(result.T_target_source[0], 1, 1e-9);
  // Too few points: an error status and message, not an exception.
  s.num_points = t.num_points = 2;
  EXPECT_EQ(table->align(instance.raw(), &s, &t, identity, 1, &result, &err), LF_ERROR);
  EXPECT_NE(std::string(err.message).find("fewer than min_points"), std::string::npos);
}

TEST_F(Components, BadComponentRequestsFailTheRunWithAReason) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"registration/kabsch_tset", "unknown component stage 'registration/kabsch_tset' (did you "
                                   "mean 'registration/kabsch_test'?)"},
      {"test/align_check", "stage 'test/align_check' is not a component"}};
  for (const auto& [backend, reason] : cases) {
    StageRun run{&registry_, "test/align_check", {{"backend", backend}}, {}, {}};
    run.options.output_dir = dir_ / "bad";
    try {
      run();
      FAIL() << backend;
    } catch (const locforge::Error& e) {
      EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
    }
  }
  locforge::runtime::SetComponentRegistry(nullptr);
  StageRun run{&registry_, "test/align_check", {}, {}, {}};
  run.options.output_dir = dir_ / "bad";
  EXPECT_THROW(run(), locforge::Error);
}

TEST(TestKit, AcceptsGoodPlugins) {
  for (const fs::path& lib : {kExamples, kTestPlugins / "liblftest_components.so",
                              kTestPlugins / "liblftest_items.so"}) {
    const auto report = locforge::testkit::CheckPlugin(lib);
    EXPECT_TRUE(report.ok()) << lib << "\n" << report.ToString();
  }
}

TEST(TestKit, ReportsBrokenPlugins) {
  const auto refused = locforge::testkit::CheckPlugin(BrokenLib("abi_v2"));
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.failures[0].find("libabi_v2.so: plugin ABI version 2"), std::string::npos)
      << refused.ToString();

  const auto lax = locforge::testkit::CheckPlugin(BrokenLib("lax_params"));
  ASSERT_FALSE(lax.ok());
  const std::string text = lax.ToString();
  EXPECT_NE(text.find("parameter 'iterations' has no doc"), std::string::npos) << text;
  EXPECT_NE(text.find("locforge_testkit_unknown"), std::string::npos) << text;
  EXPECT_NE(text.find("{iterations=11} (above the maximum)"), std::string::npos) << text;
  EXPECT_NE(text.find("{iterations=-1} (below the minimum)"), std::string::npos) << text;
  EXPECT_NE(text.find("{iterations=not_a_number} (not an integer) returned status 0"), std::string::npos) << text;
}

}  // namespace

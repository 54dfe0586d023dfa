// End-to-end tests of the built `locforge` binary on graphs in a temp folder,
// using the example plugin's stages (source/synthetic_images,
// source/image_list, example/image_stats).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <regex>
#include <sstream>
#include <thread>

#include "testing.h"

namespace locforge::host {
namespace {

namespace fs = std::filesystem;

std::string Env(const char* name, const char* fallback) {
  const char* v = std::getenv(name);
  return v && *v ? v : fallback;
}

std::string Bin() { return Env("LOCFORGE_BIN", LOCFORGE_BIN_DEFAULT); }
std::string PluginDir() { return Env("LOCFORGE_PLUGIN_DIR", LOCFORGE_PLUGIN_DIR_DEFAULT); }

std::string ReadAll(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

struct Result {
  int rc = -1;
  std::string out, err;
};

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = locforge::testing::MakeTempDir("lf-cli");
    ASSERT_TRUE(fs::exists(Bin())) << "locforge binary not found: " << Bin();
    ASSERT_TRUE(fs::exists(fs::path(PluginDir()) / "liblocforge_examples.so"))
        << "the examples plugin is not built in " << PluginDir();
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  // Only the build's plugin folder: other folders must not change results.
  std::string EnvPrefix() const {
    return "LOCFORGE_NO_DEFAULT_PLUGINS=1 LOCFORGE_PLUGIN_PATH='" + PluginDir() + "' ";
  }

  Result Run(const std::string& args) {
    const fs::path out = dir_ / "stdout.txt", err = dir_ / "stderr.txt";
    const std::string cmd = "cd '" + dir_.string() + "' && " + EnvPrefix() + "'" + Bin() + "' " +
                            args + " > '" + out.string() + "' 2> '" + err.string() + "'";
    const int status = std::system(cmd.c_str());
    Result r;
    r.rc = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = ReadAll(out);
    r.err = ReadAll(err);
    return r;
  }

  fs::path Write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    fs::create_directories(p.parent_path());
    std::ofstream(p) << text;
    return p;
  }

  // Status column of `node` in the timing table ("" when absent).
  static std::string Status(const std::string& table, const std::string& node,
                            const std::string& variant = "") {
    std::istringstream in(table);
    std::string line;
    while (std::getline(in, line)) {
      std::istringstream cols(line);
      std::vector<std::string> c;
      for (std::string w; cols >> w;) c.push_back(w);
      const size_t off = variant.empty() ? 0 : 1;
      if (c.size() >= 4 + off && c[off] == node && (variant.empty() || c[0] == variant))
        return c[2 + off];
    }
    return "";
  }

  // Every file under the workspace cache with its modification time.
  std::map<std::string, int64_t> Snapshot(const fs::path& ws) {
    std::map<std::string, int64_t> out;
    for (const auto& e : fs::recursive_directory_iterator(ws / "cache"))
      out[e.path().string()] = e.last_write_time().time_since_epoch().count();
    return out;
  }

  fs::path dir_;
};

const char kDemo[] = R"(locforge: 1
vars:
  count: 6
nodes:
  images:
    stage: source/synthetic_images
    params: {count: "${count}", width: 32, height: 24}
  stats:
    stage: example/image_stats
    inputs: {images: images.images}
    params: {bins: 16}
)";

TEST_F(Cli, VersionHelpAndUnknownCommand) {
  Result r = Run("--version");
  EXPECT_EQ(r.rc, 0);
  EXPECT_EQ(r.out.rfind("locforge ", 0), 0u) << r.out;
  for (const std::string cmd : {"--help", "help", "help run", "help validate", "help plugins",
                                "run --help", "validate --help", "plugins --help", "help --help"}) {
    r = Run(cmd);
    EXPECT_EQ(r.rc, 0) << cmd << ": " << r.err;
    EXPECT_NE(r.out.find("Usage"), std::string::npos) << cmd << ": " << r.out;
  }
  EXPECT_NE(Run("help run").out.find("--workspace DIR"), std::string::npos);
  EXPECT_NE(Run("run --help").out.find("relative to"), std::string::npos);
  r = Run("rnu x.yaml");
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("unknown command 'rnu' (did you mean 'run'?)"), std::string::npos) << r.err;
  r = Run("run");
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("expected a graph file"), std::string::npos) << r.err;
  r = Run("run g.yaml --workspace w --thread 3");
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("unknown option '--thread' (did you mean '--threads'?)"), std::string::npos)
      << r.err;
}

TEST_F(Cli, PluginsListAndRefusedLibraries) {
  Write("broken/libbroken.so", "this is not an ELF file");
  Result r = Run("plugins list --plugin-path broken");
  EXPECT_EQ(r.rc, 0) << r.err;
  for (const char* id : {"source/synthetic_images", "source/image_list", "example/image_stats"})
    EXPECT_NE(r.out.find(id), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("liblocforge_examples.so"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("examples 1."), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("warning: plugin " + (dir_ / "broken" / "libbroken.so").string() +
                       " refused and skipped: "),
            std::string::npos)
      << r.err;
}

TEST_F(Cli, PluginsListFailsOnDuplicates) {
  fs::create_directories(dir_ / "copy");
  fs::copy_file(fs::path(PluginDir()) / "liblocforge_examples.so",
                dir_ / "copy" / "liblocforge_examples_copy.so");
  Result r = Run("plugins list --plugin-path copy");
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("duplicate"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("liblocforge_examples_copy.so"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find((fs::path(PluginDir()) / "liblocforge_examples.so").string()),
            std::string::npos)
      << r.err;
}

TEST_F(Cli, PluginsDescribe) {
  Result r = Run("plugins describe example/image_stats");
  EXPECT_EQ(r.rc, 0) << r.err;
  for (const char* text :
       {"example/image_stats", "per-item", "bins  (int)  default: 16", "range: [1, 256]",
        "Histogram bins", "images: kapture.dataset  (required)", "stats: report",
        "component interface: none", "plugin: examples"})
    EXPECT_NE(r.out.find(text), std::string::npos) << text << "\n" << r.out;
  r = Run("plugins describe source/image_list");
  EXPECT_NE(r.out.find("root  (path)  required"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("whole"), std::string::npos) << r.out;
  r = Run("plugins describe example/image_stat");
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("did you mean 'example/image_stats'"), std::string::npos) << r.err;
}

// One graph per refusal class; each must exit 2 with FILE:LINE:COLUMN and the reason.
struct BadGraph {
  const char* name;
  const char* body;  // after "locforge: 1\n"
  const char* expected;
};

TEST_F(Cli, ValidateRefusesEachErrorClass) {
  Write("broken/libbroken.so", "not a library");
  const BadGraph cases[] = {
      {"unknown_stage", "nodes:\n  a: {stage: source/synthetic_image}\n",
       ":3:14: error: node 'a': unknown stage 'source/synthetic_image' (did you mean "
       "'source/synthetic_images'?)"},
      {"unknown_param", "nodes:\n  a: {stage: source/synthetic_images, params: {cuont: 3}}\n",
       ":3:48: error: node 'a': stage 'source/synthetic_images' has no parameter 'cuont' (did you "
       "mean 'count'?)"},
      {"mistyped_param", "nodes:\n  a: {stage: source/synthetic_images, params: {count: lots}}\n",
       ":3:55: error: node 'a': parameter 'count' (int): expected an integer, got 'lots'"},
      {"out_of_range", "nodes:\n  a: {stage: source/synthetic_images, params: {width: 2}}\n",
       ":3:55: error: node 'a': parameter 'width' (int): value 2 is out of range [8, 16384]"},
      {"required_param", "nodes:\n  a: {stage: source/image_list}\n",
       ":3:3: error: node 'a': required parameter 'root' (path"},
      {"missing_path",
       "nodes:\n  a: {stage: source/image_list, params: {root: ./no_such_folder}}\n",
       ":3:48: error: node 'a': parameter 'root' (path): '"},
      {"unknown_node",
       "nodes:\n  a: {stage: source/synthetic_images}\n  s: {stage: example/image_stats, inputs: "
       "{images: b.images}}\n",
       ":4:52: error: node 's': input 'images' reads unknown node 'b' (did you mean 'a'?)"},
      {"unknown_port",
       "nodes:\n  a: {stage: source/synthetic_images}\n  s: {stage: example/image_stats, inputs: "
       "{images: a.imgs}}\n",
       ":4:52: error: node 's': node 'a' (source/synthetic_images) has no output 'imgs'"},
      {"unknown_input",
       "nodes:\n  a: {stage: source/synthetic_images}\n  s: {stage: example/image_stats, inputs: "
       "{imgs: a.images}}\n",
       ":4:44: error: node 's': stage 'example/image_stats' has no input 'imgs' (did you mean "
       "'images'?)"},
      {"type_mismatch",
       "nodes:\n  a: {stage: source/synthetic_images}\n  s: {stage: example/image_stats, inputs: "
       "{images: a.images}}\n  t: {stage: example/image_stats, inputs: {images: s.stats}}\n",
       ":5:52: error: node 't': input 'images' expects artifact type 'kapture.dataset' but s.stats "
       "gives 'report'"},
      {"unwired_input", "nodes:\n  s: {stage: example/image_stats}\n",
       ":3:3: error: node 's': required input 'images' (kapture.dataset) is not wired"},
      {"cycle",
       "nodes:\n  s: {stage: example/image_stats, inputs: {images: t.stats}}\n  t: {stage: "
       "example/image_stats, inputs: {images: s.stats}}\n",
       ":3:3: error: cycle in the graph: s -> t -> s"},
      {"unknown_var",
       "vars: {count: 3}\nnodes:\n  a: {stage: source/synthetic_images, params: {count: "
       "\"${cont}\"}}\n",
       ":4:55: error: unknown variable 'cont' (did you mean 'count'?)"},
      {"duplicate_key",
       "nodes:\n  a: {stage: source/synthetic_images}\n  a: {stage: source/synthetic_images}\n",
       ":4:3: error: duplicate key 'a'"},
      {"plugin_refused", "plugin_paths: [broken]\nnodes:\n  a: {stage: source/synthetic_images}\n",
       ": error: plugin "},
  };
  for (const auto& c : cases) {
    const fs::path g = Write(std::string(c.name) + ".yaml", std::string("locforge: 1\n") + c.body);
    const Result r = Run("validate " + g.filename().string());
    EXPECT_EQ(r.rc, 2) << c.name << ": " << r.out << r.err;
    EXPECT_NE(r.err.find(g.filename().string() + c.expected), std::string::npos)
        << c.name << ": expected '" << c.expected << "' in:\n"
        << r.err;
    const Result run = Run("run " + g.filename().string() + " --workspace ws");
    EXPECT_EQ(run.rc, 2) << c.name;
    EXPECT_FALSE(fs::exists(dir_ / "ws" / "cache")) << c.name << ": nothing may run";
  }
  // Component-only stages are refused as nodes (no example stage is one; see graph_test).
  const Result set = Run("validate unknown_param.yaml --set a.count=0");
  EXPECT_NE(
      set.err.find(
          "--set a.count=0: error: node 'a': parameter 'count' (int): value 0 is out of range"),
      std::string::npos)
      << set.err;
}

TEST_F(Cli, ValidateAcceptsTheExamples) {
  Write("demo.yaml", kDemo);
  Result r = Run("validate demo.yaml");
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("ok, 2 nodes"), std::string::npos) << r.out;
  const fs::path examples = fs::path(LOCFORGE_SOURCE_DIR) / "configs" / "examples";
  for (const char* name : {"demo.yaml", "matrix.yaml"}) {
    r = Run("validate '" + (examples / name).string() + "'");
    EXPECT_EQ(r.rc, 0) << name << ": " << r.err;
  }
}

// configs/ holds runnable graphs only: each validates against the built
// plugins (every required variable given: an existing folder for "DIR: ...",
// an existing file for "FILE: ..."), and a required variable left out says
// how to give it before anything runs.
TEST_F(Cli, EveryShippedGraphValidatesAndRequiredVariablesSayWhatToDo) {
  const fs::path shared = locforge::testing::SharedDir();
  if (!fs::exists(shared / "data")) {
    if (locforge::testing::SharedRequired()) FAIL() << "shared data missing and LOCFORGE_REQUIRE_SHARED=1";
    GTEST_SKIP() << "the shipped graphs read ../shared: absent, set LOCFORGE_SHARED_DIR";
  }
  const fs::path configs = fs::path(LOCFORGE_SOURCE_DIR) / "configs";
  const fs::path recording = dir_ / "recording";
  fs::create_directories(recording);
  const fs::path file = dir_ / "a_file";
  Write("a_file", "x");
  const std::regex required_var(R"re(^\s+(\w+): !required "(DIR|FILE): ([^"]*)")re");
  int graphs = 0, with_required = 0;
  for (const auto& e : fs::recursive_directory_iterator(configs)) {
    if (e.path().extension() != ".yaml") continue;
    ++graphs;
    std::istringstream text(ReadAll(e.path()));
    std::string sets;
    std::vector<std::string> messages;
    for (std::string line; std::getline(text, line);) {
      std::smatch m;
      if (!std::regex_search(line, m, required_var)) continue;
      sets += " --set " + m[1].str() + "=" + (m[2] == "DIR" ? recording : file).string();
      messages.push_back("error: variable '" + m[1].str() + "' is required (" + m[2].str() + ": " + m[3].str() +
                         "): give it with --set " + m[1].str() + "=" + m[2].str());
    }
    const Result r = Run("validate '" + e.path().string() + "'" + sets);
    EXPECT_EQ(r.rc, 0) << e.path() << ": " << r.err;
    if (!messages.empty()) {
      ++with_required;
      const Result missing = Run("validate '" + e.path().string() + "'");
      EXPECT_EQ(missing.rc, 2) << e.path();
      for (const std::string& message : messages)
        EXPECT_NE(missing.err.find(message), std::string::npos) << e.path() << ": " << missing.err;
    }
  }
  EXPECT_GE(graphs, 15);
  EXPECT_GE(with_required, 5);
}

// The report of a run: one HTML file naming the CSV it shows, the run record
// beside the log.
TEST_F(Cli, ReportOfARun) {
  Write("demo.yaml", kDemo);
  ASSERT_EQ(Run("run demo.yaml --workspace ws").rc, 0);
  ASSERT_EQ(Run("run demo.yaml --workspace ws").rc, 0);  // the report shows this (cached) run
  int records = 0;
  for (const auto& e : fs::directory_iterator(dir_ / "ws" / "logs")) records += e.path().extension() == ".json";
  EXPECT_EQ(records, 2);
  Result r = Run("report ws");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(r.out, "report: ws/report.html\n");
  const std::string html = ReadAll(dir_ / "ws" / "report.html");
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_NE(html.find("<td>stats</td><td>example/image_stats</td><td>"), std::string::npos);
  EXPECT_NE(html.find("<td>cached</td>"), std::string::npos);
  EXPECT_EQ(html.find("<td>ran</td>"), std::string::npos) << "the last run computed nothing";
  EXPECT_EQ(html.find("http"), std::string::npos) << "nothing loaded from elsewhere";
  r = Run("report ws -o out/r.html");
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir_ / "out" / "r.html"));
  r = Run("report nowhere");
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("is not a workspace"), std::string::npos) << r.err;
}

TEST_F(Cli, RunThenRerunIsCachedAndTouchesNothing) {
  Write("demo.yaml", kDemo);
  Result r = Run("run demo.yaml --workspace ws --threads 2");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(Status(r.out, "images"), "ran") << r.out;
  EXPECT_EQ(Status(r.out, "stats"), "ran") << r.out;
  EXPECT_NE(r.out.find((dir_ / "ws" / "nodes" / "stats").string()), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(dir_ / "ws" / "nodes" / "stats" / "stats.csv"));
  EXPECT_TRUE(fs::exists(dir_ / "ws" / "nodes" / "stats" / ".locforge-complete"));
  const std::string manifest = ReadAll(dir_ / "ws" / "nodes" / "stats" / ".locforge-complete");
  EXPECT_NE(manifest.find("\"stage\": \"example/image_stats\""), std::string::npos) << manifest;
  EXPECT_NE(manifest.find("\"bins\": \"16\""), std::string::npos) << manifest;
  // The log holds what the console showed.
  bool logged = false;
  for (const auto& e : fs::directory_iterator(dir_ / "ws" / "logs"))
    logged |= ReadAll(e.path()).find("stats: ran") != std::string::npos;
  EXPECT_TRUE(logged);
  EXPECT_EQ(r.err.find('\r'), std::string::npos) << "no carriage returns off a terminal";

  const auto before = Snapshot(dir_ / "ws");
  r = Run("run demo.yaml --workspace ws");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(Status(r.out, "images"), "cached") << r.out;
  EXPECT_EQ(Status(r.out, "stats"), "cached") << r.out;
  EXPECT_EQ(Snapshot(dir_ / "ws"), before);
}

TEST_F(Cli, SetRerunsOnlyAffectedNodesAndForceRerunsAll) {
  Write("demo.yaml", kDemo);
  ASSERT_EQ(Run("run demo.yaml --workspace ws").rc, 0);
  const fs::path images_before = fs::read_symlink(dir_ / "ws" / "nodes" / "images");
  const fs::path stats_before = fs::read_symlink(dir_ / "ws" / "nodes" / "stats");
  Result r = Run("run demo.yaml --workspace ws --set stats.bins=4");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(Status(r.out, "images"), "cached") << r.out;
  EXPECT_EQ(Status(r.out, "stats"), "ran") << r.out;
  EXPECT_EQ(fs::read_symlink(dir_ / "ws" / "nodes" / "images"), images_before);
  EXPECT_NE(fs::read_symlink(dir_ / "ws" / "nodes" / "stats"), stats_before);
  r = Run("run demo.yaml --workspace ws --set count=3");
  EXPECT_EQ(Status(r.out, "images"), "ran") << r.out;
  EXPECT_EQ(Status(r.out, "stats"), "ran") << r.out;
  // Back to the first parameters: both folders are still in the cache.
  r = Run("run demo.yaml --workspace ws");
  EXPECT_EQ(Status(r.out, "images"), "cached") << r.out;
  EXPECT_EQ(Status(r.out, "stats"), "cached") << r.out;
  EXPECT_EQ(fs::read_symlink(dir_ / "ws" / "nodes" / "stats"), stats_before);
  r = Run("run demo.yaml --workspace ws --force");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(Status(r.out, "images"), "ran") << r.out;
  EXPECT_EQ(Status(r.out, "stats"), "ran") << r.out;
  EXPECT_EQ(fs::read_symlink(dir_ / "ws" / "nodes" / "stats"), stats_before);  // same key
}

TEST_F(Cli, MatrixVariantsShareIdenticalNodes) {
  Write("matrix.yaml", R"(locforge: 1
matrix:
  seed: [0, 1]
  bins: [4, 8]
nodes:
  images: {stage: source/synthetic_images, params: {count: 3, width: 16, height: 16, seed: "${seed}"}}
  stats: {stage: example/image_stats, inputs: {images: images.images}, params: {bins: "${bins}"}}
)");
  Result r = Run("run matrix.yaml --workspace ws");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(Status(r.out, "images", "seed=0,bins=4"), "ran") << r.out;
  EXPECT_EQ(Status(r.out, "images", "seed=0,bins=8"), "cached") << r.out;
  EXPECT_EQ(Status(r.out, "images", "seed=1,bins=4"), "ran") << r.out;
  EXPECT_EQ(Status(r.out, "stats", "seed=1,bins=8"), "ran") << r.out;
  size_t images = 0, stats = 0;
  for (const auto& e : fs::directory_iterator(dir_ / "ws" / "cache")) {
    const std::string name = e.path().filename().string();
    images += name.rfind("images-", 0) == 0;
    stats += name.rfind("stats-", 0) == 0;
  }
  EXPECT_EQ(images, 2u);
  EXPECT_EQ(stats, 4u);
  const fs::path v = dir_ / "ws" / "variants";
  EXPECT_EQ(fs::canonical(v / "seed=0,bins=4" / "nodes" / "images"),
            fs::canonical(v / "seed=0,bins=8" / "nodes" / "images"));
  EXPECT_TRUE(fs::exists(v / "seed=1,bins=8" / "nodes" / "stats" / "stats.csv"));
  r = Run("run matrix.yaml --workspace ws --variant seed=1,bins=8");
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(Status(r.out, "stats", "seed=1,bins=8"), "cached") << r.out;
  EXPECT_EQ(Status(r.out, "stats", "seed=0,bins=4"), "") << r.out;
  r = Run("run matrix.yaml --workspace ws --variant seed=1,bins=9");
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("unknown variant (did you mean 'seed=1,bins="), std::string::npos) << r.err;
}

TEST_F(Cli, CollectTabulatesEveryVariantInNumberOrderWithASummary) {
  Write("ws/variants/seed=10/nodes/joins/summary.json", R"({"right": 2, "wrong": 0, "ate_m": 0.004, "e": {"a": [1, 2]}})");
  Write("ws/variants/seed=2/nodes/joins/summary.json", R"({"right": 1, "wrong": 1, "ate_m": 0.002, "e": {"a": [3, 4]}})");
  fs::create_directories(dir_ / "ws/variants/seed=3/nodes/joins");  // not run yet: no file
  Result r = Run("collect ws joins/summary.json --summary");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(r.out,
            "variant,right,wrong,ate_m,e.a.0,e.a.1\n"
            "seed=2,1,1,0.002,3,4\n"
            "seed=10,2,0,0.004,1,2\n"
            "(count),2,2,2,2,2\n"
            "(mean),1.5,0.5,0.003,2,3\n"
            "(min),1,0,0.002,1,2\n"
            "(max),2,1,0.004,3,4\n")
      << r.out;
  EXPECT_NE(r.err.find("seed=3"), std::string::npos) << r.err;  // the missing file is named
  r = Run("collect ws joins/summary.json --format md -o table.md");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(ReadAll(dir_ / "table.md").find("| seed=2 | 1 | 1 | 0.002 | 3 | 4 |"), std::string::npos);
  Write("ws/variants/seed=4/nodes/joins/summary.json", "{not json");
  r = Run("collect ws joins/summary.json");
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("seed=4/nodes/joins/summary.json"), std::string::npos) << r.err;
}

TEST_F(Cli, FailingStageExitsOneNamingTheNode) {
  Write("bad/x.png", "not a png");
  Write("list.yaml", R"(locforge: 1
nodes:
  imgs: {stage: source/image_list, params: {root: bad}}
  stats: {stage: example/image_stats, inputs: {images: imgs.images}}
)");
  const Result r = Run("run list.yaml --workspace ws");
  EXPECT_EQ(r.rc, 1);
  EXPECT_EQ(Status(r.out, "imgs"), "failed") << r.out;
  EXPECT_EQ(Status(r.out, "stats"), "skipped") << r.out;
  EXPECT_NE(r.err.find("error: node 'imgs' (source/image_list) failed: "), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("x.png"), std::string::npos) << r.err;
}

TEST_F(Cli, InterruptedPerItemRunResumes) {
  const std::string images =
      "  images: {stage: source/synthetic_images, params: {count: 200, width: 480, height: 360}}\n";
  Write("images.yaml", "locforge: 1\nnodes:\n" + images);
  Write("slow.yaml",
        "locforge: 1\nnodes:\n" + images +
            "  stats: {stage: example/image_stats, inputs: {images: images.images}}\n");
  // Same node, same key: the images are cached for slow.yaml.
  ASSERT_EQ(Run("run images.yaml --workspace ws").rc, 0);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const std::string cmd = "cd '" + dir_.string() + "' && " + EnvPrefix() + "exec '" + Bin() +
                            "' run slow.yaml --workspace ws --threads 1 > run1.out 2> run1.err";
    execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  // Interrupt once some items are journaled.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  size_t journaled = 0;
  while (std::chrono::steady_clock::now() < deadline && journaled < 10) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    for (const auto& e : fs::directory_iterator(dir_ / "ws" / "cache")) {
      const fs::path j = e.path() / ".items-done.0-of-1";
      if (e.path().extension() == ".partial" && fs::exists(j)) {
        const std::string text = ReadAll(j);
        journaled = std::count(text.begin(), text.end(), '\n');
      }
    }
  }
  ASSERT_GE(journaled, 10u);
  kill(pid, SIGINT);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  const std::string out1 = ReadAll(dir_ / "run1.out");
  EXPECT_EQ(Status(out1, "stats"), "failed") << out1;
  EXPECT_NE(ReadAll(dir_ / "run1.err").find("interrupted"), std::string::npos);

  const Result r = Run("run slow.yaml --workspace ws --threads 2");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(Status(r.out, "images"), "cached") << r.out;
  EXPECT_EQ(Status(r.out, "stats"), "resumed") << r.out;
  EXPECT_NE(r.out.find("resumed    200"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(std::istreambuf_iterator<char>(
                           std::ifstream(dir_ / "ws" / "nodes" / "stats" / "stats.csv").rdbuf()),
                       std::istreambuf_iterator<char>(), '\n'),
            201)
      << "header + one line per image";
}

TEST_F(Cli, ShardsThenFinalRunComplete) {
  Write("demo.yaml", kDemo);
  Result r = Run("run demo.yaml --workspace ws --shard 0/2 --set count=12");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(Status(r.out, "images"), "ran") << r.out;
  EXPECT_EQ(Status(r.out, "stats"), "partial") << r.out;
  EXPECT_NE(r.err.find("shard 0/2 done"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "ws" / "nodes" / "stats"));
  r = Run("run demo.yaml --workspace ws --shard 1/2 --set count=12");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(Status(r.out, "images"), "cached") << r.out;
  EXPECT_EQ(Status(r.out, "stats"), "ran") << r.out;  // the last shard finalizes
  r = Run("run demo.yaml --workspace ws --set count=12");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(Status(r.out, "stats"), "cached") << r.out;
  EXPECT_TRUE(fs::exists(dir_ / "ws" / "nodes" / "stats" / "stats.csv"));
  EXPECT_EQ(Run("run demo.yaml --workspace ws --shard 2/2").rc, 2);
  EXPECT_EQ(Run("run demo.yaml --workspace ws --shard 0/2 --force").rc, 2);
}

// Every output file of a node folder (bookkeeping files left out): path -> bytes.
std::map<std::string, std::string> Contents(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file() && e.path().filename().string()[0] != '.')
      out[e.path().lexically_relative(dir).generic_string()] = ReadAll(e.path());
  return out;
}

TEST_F(Cli, DamagedCacheFolderIsFoundReportedAndComputedAgain) {
  Write("demo.yaml", kDemo);
  Result r = Run("run demo.yaml --workspace ws");
  ASSERT_EQ(r.rc, 0) << r.err;
  const fs::path images = fs::canonical(dir_ / "ws/nodes/images");
  const fs::path stats = fs::canonical(dir_ / "ws/nodes/stats");
  const auto images_before = Contents(images), stats_before = Contents(stats);
  EXPECT_TRUE(std::regex_search(ReadAll(images / ".locforge-complete"),
                                std::regex("\"files_sha256\": \"[0-9a-f]{64}\"")));
  r = Run("status ws --verify");
  EXPECT_EQ(r.rc, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("verified 2 node folders"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("0 damaged, 0 unverifiable"), std::string::npos) << r.out;

  // One image of the upstream node deleted: --verify names the folder and file.
  std::string victim;
  for (const auto& [path, bytes] : images_before)
    if (victim.empty() && path.find("records_data/") != std::string::npos) victim = path;
  ASSERT_FALSE(victim.empty());
  fs::remove(images / victim);
  r = Run("status ws --verify");
  EXPECT_EQ(r.rc, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("damaged cache/" + images.filename().string() + " (node images):"),
            std::string::npos) << r.out;
  EXPECT_NE(r.out.find("  " + victim + ": missing"), std::string::npos) << r.out;

  // A run warns, naming the node and the file, and computes the node again
  // to the same bytes; its downstream node stays cached, unchanged.
  r = Run("run demo.yaml --workspace ws");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.err.find("images: warning: cached folder "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(images.filename().string() + " is damaged (" + victim +
                       ": missing); computing the node again"),
            std::string::npos) << r.err;
  EXPECT_EQ(Status(r.out, "images"), "ran") << r.out;
  EXPECT_EQ(Status(r.out, "stats"), "cached") << r.out;
  EXPECT_EQ(Contents(images), images_before);
  EXPECT_EQ(Contents(stats), stats_before);
  EXPECT_EQ(Run("status ws --verify").rc, 0);

  // The same size, another content: only hashing (--verify) finds it.
  std::string csv = ReadAll(stats / "stats.csv");
  csv[csv.size() / 2] = csv[csv.size() / 2] == '7' ? '8' : '7';
  std::ofstream(stats / "stats.csv", std::ios::binary | std::ios::trunc) << csv;
  r = Run("status ws --verify");
  EXPECT_EQ(r.rc, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("  stats.csv: content changed"), std::string::npos) << r.out;

  // A manifest written before file lists: listed as unverifiable, still served.
  const std::string manifest = ReadAll(images / ".locforge-complete");
  const std::string old = std::regex_replace(
      manifest, std::regex(",\n  \"file_count\": [0-9]+,\n  \"files_sha256\": \"[0-9a-f]*\""), "");
  ASSERT_NE(old, manifest);
  std::ofstream(images / ".locforge-complete", std::ios::trunc) << old;
  r = Run("status ws --verify");
  EXPECT_NE(r.out.find("unverifiable cache/" + images.filename().string() + " (node images)"),
            std::string::npos) << r.out;
  r = Run("run demo.yaml --workspace ws");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(Status(r.out, "images"), "cached") << r.out;
}

TEST_F(Cli, ParallelShardsComputeSharedNodesOnce) {
  Write("demo.yaml", kDemo);
  const std::string bin =
      EnvPrefix() + "'" + Bin() + "' run demo.yaml --workspace ws --set count=40";
  const std::string cmd = "cd '" + dir_.string() + "' && (" + bin +
                          " --shard 0/2 > s0.out 2> s0.err & " + bin +
                          " --shard 1/2 > s1.out 2> s1.err & wait)";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  const std::string s0 = ReadAll(dir_ / "s0.out"), s1 = ReadAll(dir_ / "s1.out");
  ASSERT_NE(Status(s0, "images"), "failed") << s0 << ReadAll(dir_ / "s0.err");
  ASSERT_NE(Status(s1, "images"), "failed") << s1 << ReadAll(dir_ / "s1.err");
  // The whole node is computed by one process; the other waits on its lock.
  EXPECT_EQ((Status(s0, "images") == "ran") + (Status(s1, "images") == "ran"), 1) << s0 << s1;
  EXPECT_EQ(Status(s1, "images") == "cached" || Status(s0, "images") == "cached", true);
  for (const std::string& out : {s0, s1})
    EXPECT_TRUE(Status(out, "stats") == "partial" || Status(out, "stats") == "ran") << out;
  const Result r = Run("run demo.yaml --workspace ws --set count=40");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_TRUE(Status(r.out, "stats") == "cached" || Status(r.out, "stats") == "resumed") << r.out;
  std::ifstream csv(dir_ / "ws" / "nodes" / "stats" / "stats.csv");
  EXPECT_EQ(std::count(std::istreambuf_iterator<char>(csv), std::istreambuf_iterator<char>(), '\n'),
            41);
}

}  // namespace
}  // namespace locforge::host

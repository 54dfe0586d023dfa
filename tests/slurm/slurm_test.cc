// `locforge run --executor slurm` on a real Slurm: a one-node cluster on
// localhost (tests/slurm/cluster.sh: munged, slurmctld, slurmd, no cgroups),
// started once for this binary and stopped after. Needs root and Debian's
// slurmctld, slurmd and munge: otherwise the tests skip with a message, or
// fail under LOCFORGE_REQUIRE_SLURM=1 (CI).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "../testing/testing.h"

extern char** environ;

namespace locforge {
namespace {

namespace fs = std::filesystem;
using testing::ReadText;

const fs::path kBin = LOCFORGE_BINARY_DIR;

bool SlurmRequired() {
  const char* env = std::getenv("LOCFORGE_REQUIRE_SLURM");
  return env && std::string(env) == "1";
}

// Runs argv (no shell); returns the exit status, output into `out` when given.
int Spawn(const std::vector<std::string>& argv, const fs::path& log, pid_t* background = nullptr) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, argv[0].c_str(), &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) return -1;
  if (background) {
    *background = pid;
    return 0;
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

int WaitExit(pid_t pid) {
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string Output(const std::vector<std::string>& argv, const fs::path& scratch) {
  Spawn(argv, scratch);
  return ReadText(scratch);
}

std::vector<std::string> Host(std::vector<std::string> args) {
  args.insert(args.begin(), (kBin / "bin/locforge").string());
  return args;
}

// The cluster of this test binary.
class Cluster : public ::testing::Environment {
 public:
  void SetUp() override {
    if (::geteuid() != 0) {
      why_ = "not root: the test starts slurmctld, slurmd and munged itself";
      return;
    }
    for (const char* tool : {"/usr/sbin/slurmctld", "/usr/sbin/slurmd", "/usr/sbin/munged",
                             "/usr/bin/sbatch"})
      if (!fs::exists(tool)) {
        why_ = std::string(tool) +
               " is missing (apt-get install slurmctld slurmd munge: cmake/debian-packages.txt)";
        return;
      }
    dir_ = testing::MakeTempDir("lf-slurm-cluster");
    const fs::path script = fs::path(LOCFORGE_SOURCE_DIR) / "tests/slurm/cluster.sh";
    const int rc = Spawn({"bash", script.string(), "start", dir_.string()}, dir_.parent_path() /
                                                                             (dir_.filename().string() + ".start.log"));
    const std::string out = ReadText(dir_.parent_path() / (dir_.filename().string() + ".start.log"));
    const size_t at = out.find("SLURM_CONF=");
    if (rc != 0 || at == std::string::npos) {
      why_ = "the test cluster did not start (cluster.sh exit " + std::to_string(rc) + "): " + out;
      return;
    }
    std::string conf = out.substr(at + 11);
    conf = conf.substr(0, conf.find('\n'));
    ::setenv("SLURM_CONF", conf.c_str(), 1);
    started_ = true;
  }
  void TearDown() override {
    if (dir_.empty()) return;
    Spawn({"bash", (fs::path(LOCFORGE_SOURCE_DIR) / "tests/slurm/cluster.sh").string(), "stop",
           dir_.string()},
          "/dev/null");
    if (!::testing::UnitTest::GetInstance()->Failed()) {
      std::error_code ec;
      fs::remove_all(dir_, ec);
      fs::remove(dir_.parent_path() / (dir_.filename().string() + ".start.log"), ec);
    } else {
      std::cerr << "cluster logs kept in " << dir_ << "\n";
    }
  }
  bool started() const { return started_; }
  const std::string& why() const { return why_; }

 private:
  fs::path dir_;
  bool started_ = false;
  std::string why_;
};

Cluster* g_cluster = nullptr;

#define LOCFORGE_SLURM_OR_SKIP()                                                           \
  if (!g_cluster->started()) {                                                             \
    if (SlurmRequired()) {                                                                 \
      FAIL() << "no Slurm and LOCFORGE_REQUIRE_SLURM=1: " << g_cluster->why();             \
    } else {                                                                               \
      GTEST_SKIP() << g_cluster->why() << " (LOCFORGE_REQUIRE_SLURM=1 fails instead)";     \
    }                                                                                      \
  }

// One line of W/slurm/latest's submission: field by column.
struct JobLine {
  std::string id, variant, node, stage, key16, shards, array, log, after;
};
std::map<std::string, JobLine> LatestSubmission(const fs::path& ws) {
  std::string name = ReadText(ws / "slurm/latest");
  name = name.substr(0, name.find('\n'));
  std::istringstream in(ReadText(ws / "slurm" / name));
  std::map<std::string, JobLine> out;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> f;
    std::istringstream cells(line);
    std::string cell;
    while (std::getline(cells, cell, '\t')) f.push_back(cell);
    if (f.size() != 9) continue;
    out[f[2]] = {f[0], f[1], f[2], f[3], f[4], f[5], f[6], f[7], f[8]};
  }
  return out;
}

bool IsProtocolFile(const std::string& name) {
  return name == ".locforge-complete" || name == ".locforge-files" || name.rfind(".items-done.", 0) == 0 ||
         name.rfind(".shard-done.", 0) == 0;
}

// Complete node folders of a workspace's cache: name (node-key16) -> full key.
std::map<std::string, std::string> CompleteNodes(const fs::path& ws) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::directory_iterator(ws / "cache")) {
    if (!fs::exists(e.path() / ".locforge-complete")) continue;
    const std::string manifest = ReadText(e.path() / ".locforge-complete");
    const size_t at = manifest.find("\"key\": \"");
    out[e.path().filename().string()] =
        at == std::string::npos ? "" : manifest.substr(at + 8, 64);
  }
  return out;
}

// The fields of an output that measure the run rather than its result: the
// wall-clock seconds of the localizers' statistics and per-query results, and
// the logs of external tools (their temporary paths and elapsed times). They
// are masked ("*"); every other byte is compared.
std::string MaskWallClock(const std::string& rel, const std::string& bytes) {
  auto ends_with = [&](const std::string& suffix) {
    return rel.size() >= suffix.size() && rel.compare(rel.size() - suffix.size(), suffix.size(),
                                                      suffix) == 0;
  };
  auto split = [](const std::string& line, char sep) {
    std::vector<std::string> cells;
    std::istringstream in(line);
    std::string cell;
    while (std::getline(in, cell, sep)) cells.push_back(cell);
    return cells;
  };
  if (ends_with(".log")) return "* (a tool's log)";
  std::istringstream in(bytes);
  std::string line, out;
  if (ends_with("localization_stats.csv")) {
    // Columns whose header names seconds.
    std::vector<bool> masked;
    for (int row = 0; std::getline(in, line); ++row) {
      const auto cells = split(line, ',');
      if (row == 0)
        for (const auto& c : cells) masked.push_back(c.find("seconds") != std::string::npos);
      for (size_t i = 0; i < cells.size(); ++i)
        out += (i ? "," : "") + (i < masked.size() && masked[i] ? std::string("*") : cells[i]);
      out += "\n";
    }
    return out;
  }
  if (rel.find("/results/") != std::string::npos && ends_with(".txt")) {
    // Line 2: correspondences inliers iterations seconds.
    for (int row = 0; std::getline(in, line); ++row) {
      auto cells = split(line, ' ');
      if (row == 1 && cells.size() == 4) line = cells[0] + " " + cells[1] + " " + cells[2] + " *";
      out += line + "\n";
    }
    return out;
  }
  return bytes;
}

// Every output file of the complete nodes (protocol files left out): the
// folder name and relative path -> bytes (a link: "-> target"), wall-clock
// fields masked.
std::map<std::string, std::string> OutputFiles(const fs::path& ws) {
  std::map<std::string, std::string> out;
  for (const auto& [name, key] : CompleteNodes(ws)) {
    const fs::path dir = ws / "cache" / name;
    for (auto it = fs::recursive_directory_iterator(dir); it != fs::recursive_directory_iterator();
         ++it) {
      if (it.depth() == 0 && IsProtocolFile(it->path().filename().string())) continue;
      const std::string rel = name + "/" + it->path().lexically_relative(dir).string();
      if (it->is_symlink()) {
        // Links into the workspace name it: compare where they lead inside it.
        std::string target = fs::read_symlink(it->path()).string();
        if (target.rfind(ws.string(), 0) == 0) target = "WORKSPACE" + target.substr(ws.string().size());
        out[rel] = "-> " + target;
      }
      else if (it->is_regular_file())
        out[rel] = MaskWallClock(rel, ReadText(it->path()));
    }
  }
  return out;
}

// EXPECTs the same node folders, keys and output bytes in both workspaces.
void ExpectSameOutputs(const fs::path& a, const fs::path& b) {
  const auto nodes_a = CompleteNodes(a), nodes_b = CompleteNodes(b);
  EXPECT_EQ(nodes_a, nodes_b) << "node folders (node-key) or keys differ";
  const auto files_a = OutputFiles(a), files_b = OutputFiles(b);
  EXPECT_EQ(files_a.size(), files_b.size());
  size_t differing = 0;
  for (const auto& [rel, bytes] : files_a) {
    auto it = files_b.find(rel);
    if (it == files_b.end()) {
      ADD_FAILURE() << rel << " only in " << a;
    } else if (it->second != bytes && ++differing <= 5) {
      ADD_FAILURE() << rel << " differs (" << bytes.size() << " vs " << it->second.size()
                    << " bytes)";
    }
  }
  for (const auto& [rel, bytes] : files_b)
    if (!files_a.count(rel)) ADD_FAILURE() << rel << " only in " << b;
  EXPECT_EQ(differing, 0u);
  EXPECT_GT(files_a.size(), 0u);
}

std::string Field(const std::string& text, const std::string& key) {
  const size_t at = text.find(key + "=");
  if (at == std::string::npos) return "";
  const size_t start = at + key.size() + 1;
  return text.substr(start, text.find_first_of(" \n", start) - start);
}

// The example graph: synthetic images -> per-item image statistics, with a
// `slurm:` section.
const char kExampleGraph[] = R"(locforge: 1
vars: {count: 12}
slurm:
  default: {time: "00:10:00"}
  example: {mem: 300M}
  stats: {comment: from-the-graph}
nodes:
  images:
    stage: source/synthetic_images
    params: {count: "${count}", width: 64, height: 48}
  stats:
    stage: example/image_stats
    inputs: {images: images}
)";

TEST(Slurm, ExampleGraphResourcesStatusAndCtrlC) {
  LOCFORGE_SLURM_OR_SKIP();
  const fs::path dir = testing::MakeTempDir("lf-slurm-example");
  const fs::path graph = dir / "g.yaml";
  std::ofstream(graph) << kExampleGraph;
  ::setenv("LOCFORGE_PLUGIN_PATH", (kBin / "lib/locforge/plugins").c_str(), 1);

  ASSERT_EQ(Spawn(Host({"run", graph.string(), "--workspace", (dir / "local").string(),
                        "--threads", "1"}),
                  dir / "local.log"),
            0)
      << ReadText(dir / "local.log");
  const fs::path ws = dir / "ws";
  const std::vector<std::string> submit = {
      "run", graph.string(), "--workspace", ws.string(), "--executor", "slurm", "--shards", "3",
      "--slurm-opt", "cpus-per-task=1", "--slurm-opt", "stats:time=00:07:00"};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = submit;
    a.insert(a.end(), extra.begin(), extra.end());
    return Host(a);
  };
  // Settings locforge owns, and selectors that name nothing: refused before submitting.
  EXPECT_EQ(Spawn(with({"--slurm-opt", "array=0-3"}), dir / "bad1.log"), 2);
  EXPECT_NE(ReadText(dir / "bad1.log").find("'array' is set by locforge"), std::string::npos)
      << ReadText(dir / "bad1.log");
  EXPECT_EQ(Spawn(with({"--slurm-opt", "stat:mem=1G"}), dir / "bad2.log"), 2);
  EXPECT_NE(ReadText(dir / "bad2.log").find("did you mean 'stats'"), std::string::npos)
      << ReadText(dir / "bad2.log");
  EXPECT_FALSE(fs::exists(ws / "slurm/latest"));

  ASSERT_EQ(Spawn(with({"--wait", "--poll", "1"}), dir / "slurm.log"), 0)
      << ReadText(dir / "slurm.log");
  ExpectSameOutputs(dir / "local", ws);
  auto jobs = LatestSubmission(ws);
  ASSERT_EQ(jobs.size(), 2u);
  EXPECT_EQ(jobs["images"].array, "-");
  EXPECT_EQ(jobs["stats"].shards, "3");
  EXPECT_EQ(jobs["stats"].array, "0-2");
  EXPECT_EQ(jobs["stats"].after, jobs["images"].id);
  // The requests, as the controller recorded them: defaults, graph, command line.
  const std::string images =
      Output({"scontrol", "show", "job", jobs["images"].id}, dir / "scontrol1.txt");
  const std::string stats =
      Output({"scontrol", "show", "job", jobs["stats"].id + "_0"}, dir / "scontrol2.txt");
  EXPECT_EQ(Field(images, "TimeLimit"), "00:10:00") << images;
  EXPECT_EQ(Field(images, "MinMemoryNode"), "8G") << images;  // built-in default
  EXPECT_EQ(Field(stats, "TimeLimit"), "00:07:00") << stats;   // command line over graph
  EXPECT_EQ(Field(stats, "MinMemoryNode"), "300M") << stats;   // graph, by kind
  EXPECT_EQ(Field(stats, "Comment"), "from-the-graph") << stats;
  EXPECT_EQ(Field(stats, "NumCPUs"), "1") << stats;
  EXPECT_EQ(Field(stats, "Dependency"), "(null)") << stats;  // satisfied
  // Status: every node done, the per-item one by 3 shards, its 12 items.
  const std::string status = Output(Host({"status", ws.string()}), dir / "status.txt");
  std::istringstream lines(status);
  std::string line;
  int done = 0;
  while (std::getline(lines, line))
    if (line.find("  done  ") != std::string::npos) {
      ++done;
      if (line.rfind("stats", 0) == 0) {
        EXPECT_NE(line.find(" 12 "), std::string::npos) << line;
        EXPECT_EQ(line.back(), '3') << line;
      }
    }
  EXPECT_EQ(done, 2) << status;
  // Submitting again: everything is complete, nothing is submitted.
  ASSERT_EQ(Spawn(with({"--wait"}), dir / "again.log"), 0) << ReadText(dir / "again.log");
  EXPECT_NE(ReadText(dir / "again.log").find("0 jobs submitted, 2 nodes cached"), std::string::npos)
      << ReadText(dir / "again.log");

  // Ctrl-C of --wait cancels the jobs (held here by a begin time in an hour).
  const fs::path ws2 = dir / "ws2";
  pid_t pid = -1;
  std::vector<std::string> args = Host({"run", graph.string(), "--workspace", ws2.string(),
                                        "--executor", "slurm", "--shards", "3", "--slurm-opt",
                                        "begin=now+3600", "--wait", "--poll", "1"});
  ASSERT_EQ(Spawn(args, dir / "ctrlc.log", &pid), 0);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline &&
         ReadText(dir / "ctrlc.log").find("nodes cached; record") == std::string::npos)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ::kill(pid, SIGINT);
  EXPECT_EQ(WaitExit(pid), 1) << ReadText(dir / "ctrlc.log");
  EXPECT_NE(ReadText(dir / "ctrlc.log").find("interrupted: scancel"), std::string::npos)
      << ReadText(dir / "ctrlc.log");
  jobs = LatestSubmission(ws2);
  ASSERT_EQ(jobs.size(), 2u);
  for (const auto& [node, job] : jobs) {
    const std::string q = Output({"squeue", "--noheader", "--array", "--states=all",
                                  "--jobs=" + job.id, "--format=%T"},
                                 dir / "squeue.txt");
    EXPECT_NE(q.find("CANCELLED"), std::string::npos) << node << ": " << q;
    EXPECT_EQ(q.find("PENDING"), std::string::npos) << node << ": " << q;
  }
  if (!HasFailure()) fs::remove_all(dir);
}

// configs/benchmark/sift_densevlad.yaml on virtual_gallery_tutorial, local
// and through Slurm with 3 shards: same node keys, same bytes. Then the map
// matches and everything after them are removed, submitted again, and one
// shard of the matches is cancelled mid-way: the run reports it (node,
// shard, log); the re-submission runs only that shard (its journaled items
// kept) and what follows, and ends with the same bytes again.
TEST(Slurm, VirtualGalleryBenchmarkThreeShardsAndCancelledShard) {
  LOCFORGE_SLURM_OR_SKIP();
  LOCFORGE_SHARED_PATH_OR_SKIP(data, "data/kapture/virtual_gallery_tutorial");
  const fs::path dir = testing::MakeTempDir("lf-slurm-vg");
  ::setenv("LOCFORGE_PLUGIN_PATH", (kBin / "lib/locforge/plugins").c_str(), 1);
  const fs::path graph = fs::path(LOCFORGE_SOURCE_DIR) / "configs/benchmark/sift_densevlad.yaml";
  // A small DenseVLAD vocabulary (as the benchmark end-to-end test): the
  // graph's structure and every stage as configured, seconds not minutes.
  const std::vector<std::string> sets = {
      "--set", "map=" + (data / "mapping").string(), "--set", "query=" + (data / "query").string(),
      "--set", "vocabulary.clusters=16", "--set", "vocabulary.sample_size=20000",
      "--set", "vocabulary.max_image_size=160", "--set", "vocabulary.grid_step=8"};
  auto run = [&](const fs::path& ws, std::vector<std::string> extra) {
    std::vector<std::string> a = {"run", graph.string(), "--workspace", ws.string()};
    a.insert(a.end(), sets.begin(), sets.end());
    a.insert(a.end(), extra.begin(), extra.end());
    return Host(a);
  };
  const fs::path local = dir / "local", ws = dir / "ws";
  ASSERT_EQ(Spawn(run(local, {"--threads", "1"}), dir / "local.log"), 0)
      << ReadText(dir / "local.log");
  const std::vector<std::string> slurm = {"--executor", "slurm", "--shards", "3", "--slurm-opt",
                                          "cpus-per-task=1", "--slurm-opt", "mem=2G",
                                          "--wait", "--poll", "1"};
  ASSERT_EQ(Spawn(run(ws, slurm), dir / "slurm.log"), 0) << ReadText(dir / "slurm.log");
  ExpectSameOutputs(local, ws);
  auto jobs = LatestSubmission(ws);
  ASSERT_EQ(jobs.size(), 19u);
  // Per-item nodes as arrays of 3, whole-set ones as one job, each after its inputs' jobs.
  for (const char* node : {"map_features", "query_features", "map_global", "query_global",
                           "map_pairs", "query_pairs", "map_matches", "map_verified",
                           "query_matches", "query_verified", "pnp"})
    EXPECT_EQ(jobs[node].array, "0-2") << node;
  for (const char* node : {"map", "query", "vocabulary", "triangulation", "colmap_registrator",
                           "eval_pnp", "eval_colmap", "table"})
    EXPECT_EQ(jobs[node].array, "-") << node;
  // map_matches reads the map's poses too (its optional epipolar band).
  const std::set<std::string> inputs = {jobs["map_features"].id, jobs["map_pairs"].id, jobs["map"].id};
  std::string after;
  for (const std::string& id : inputs) after += (after.empty() ? "" : ",") + id;
  EXPECT_EQ(jobs["map_matches"].after, after);

  // The map matches and everything after them, as if never computed.
  const std::set<std::string> downstream = {"map_matches", "map_verified", "triangulation", "pnp",
                                            "colmap_registrator", "eval_pnp", "eval_colmap",
                                            "table"};
  for (const auto& e : fs::directory_iterator(ws / "cache")) {
    std::string name = e.path().filename().string();  // NODE-KEY16[.partial]
    name = name.substr(0, name.find('.'));
    if (downstream.count(name.substr(0, name.rfind('-')))) fs::remove_all(e.path());
  }
  EXPECT_EQ(CompleteNodes(ws).size(), 19u - downstream.size());
  pid_t pid = -1;
  ASSERT_EQ(Spawn(run(ws, slurm), dir / "cut.log", &pid), 0);
  // Cancel shard 1 of the matches once it journaled an item (and before it is done).
  fs::path partial;
  std::string job;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(600);
  bool cancelled = false;
  while (!cancelled && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (job.empty() && fs::exists(ws / "slurm/latest")) {
      auto now = LatestSubmission(ws);
      if (now.count("table") && now["map_matches"].id != jobs["map_matches"].id) {
        job = now["map_matches"].id;
        partial = ws / "cache" / ("map_matches-" + now["map_matches"].key16 + ".partial");
      }
    }
    if (job.empty()) continue;
    const std::string journal = ReadText(partial / ".items-done.1-of-3");
    if (journal.find('\n') != std::string::npos) {
      ASSERT_EQ(Spawn({"scancel", job + "_1"}, dir / "scancel.log"), 0)
          << ReadText(dir / "scancel.log");
      cancelled = true;
    }
  }
  ASSERT_TRUE(cancelled) << ReadText(dir / "cut.log");
  EXPECT_EQ(WaitExit(pid), 1) << ReadText(dir / "cut.log");
  const std::string cut = ReadText(dir / "cut.log");
  const std::string shard_log = (ws / "logs/slurm" / ("map_matches-" + job + "_1.log")).string();
  EXPECT_NE(cut.find("node 'map_matches' shard 1/3 (job " + job + "_1) CANCELLED; log: " +
                     shard_log),
            std::string::npos)
      << cut;
  EXPECT_TRUE(fs::exists(shard_log));
  ASSERT_FALSE(fs::exists(partial / ".shard-done.1-of-3"))
      << "shard 1 finished before it was cancelled: nothing to resume";
  const std::string journaled = ReadText(partial / ".items-done.1-of-3");
  // The other shards were not cancelled: they finished and left their records.
  const std::string record0 = ReadText(partial / ".shard-done.0-of-3");
  const std::string record2 = ReadText(partial / ".shard-done.2-of-3");
  EXPECT_FALSE(record0.empty());
  EXPECT_FALSE(record2.empty());
  const std::string status = Output(Host({"status", ws.string()}), dir / "status.txt");
  EXPECT_NE(status.find("failed (2/3 shards done"), std::string::npos) << status;

  // Re-submit: only shard 1 of the matches, then what follows.
  ASSERT_EQ(Spawn(run(ws, slurm), dir / "resume.log"), 0) << ReadText(dir / "resume.log");
  jobs = LatestSubmission(ws);
  EXPECT_EQ(jobs["map_matches"].array, "1");
  size_t submitted = 0;
  for (const auto& [node, j] : jobs) {
    submitted += j.id != "-";
    EXPECT_EQ(j.id != "-", downstream.count(node) > 0) << node;
  }
  EXPECT_EQ(submitted, downstream.size());
  // Shard 1 kept its journaled items and went on from there; shards 0 and 2
  // did not run again.
  const fs::path matches = ws / "cache" / ("map_matches-" + jobs["map_matches"].key16);
  const std::string finished = ReadText(matches / ".items-done.1-of-3");
  EXPECT_EQ(finished.substr(0, journaled.size()), journaled);
  EXPECT_GT(finished.size(), journaled.size());
  std::set<std::string> items;
  std::istringstream in(finished);
  std::string item;
  size_t lines = 0;
  while (std::getline(in, item)) items.insert(item), ++lines;
  EXPECT_EQ(items.size(), lines) << "an item was processed twice";
  EXPECT_EQ(ReadText(matches / ".shard-done.0-of-3"), record0);
  EXPECT_EQ(ReadText(matches / ".shard-done.2-of-3"), record2);
  ExpectSameOutputs(local, ws);
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace locforge

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  locforge::g_cluster = new locforge::Cluster;
  ::testing::AddGlobalTestEnvironment(locforge::g_cluster);
  return RUN_ALL_TESTS();
}

// Slurm submission pieces that need no cluster: option parsing, the
// precedence of resource requests, their checks; the usage meter. The
// cluster itself: tests/slurm.
#include "slurm.h"

#include <gtest/gtest.h>

#include <vector>

#include "process.h"
#include "test_stages.h"
#include "usage.h"

namespace locforge::host {
namespace {

class SchedulerSettings : public ::testing::Test {
 protected:
  ResolvedNode Node(const std::string& name, const std::string& stage) {
    ResolvedNode n;
    n.name = name;
    n.stage = stages_.Find(stage);
    return n;
  }
  std::vector<ResolvedGraph> Graph() {
    ResolvedGraph g;
    g.nodes = {Node("images", "source/images"), Node("feats", "features/sift"),
               Node("poses", "slam/graph")};
    return {g};
  }
  static SchedulerSetting Opt(const std::string& text) {
    SchedulerSetting s;
    EXPECT_TRUE(ParseSchedulerSetting(text, &s)) << text;
    return s;
  }
  testing::FakeStages stages_;
};

TEST_F(SchedulerSettings, ParsesSelectorOptionAndValue) {
  SchedulerSetting s = Opt("mem=4G");
  EXPECT_EQ(s.selector, "default");
  EXPECT_EQ(s.key, "mem");
  EXPECT_EQ(s.value, "4G");
  s = Opt("features/sift:time=1:00:00");  // the value may hold ':' and '='
  EXPECT_EQ(s.selector, "features/sift");
  EXPECT_EQ(s.key, "time");
  EXPECT_EQ(s.value, "1:00:00");
  s = Opt("comment=a=b");
  EXPECT_EQ(s.value, "a=b");
  EXPECT_FALSE(ParseSchedulerSetting("mem", &s));
  EXPECT_FALSE(ParseSchedulerSetting("=4G", &s));
  EXPECT_FALSE(ParseSchedulerSetting("feats:=4G", &s));
}

TEST_F(SchedulerSettings, DefaultsThenGraphThenCommandLineBySpecificity) {
  const ResolvedNode feats = Node("feats", "features/sift");
  const ResolvedNode poses = Node("poses", "slam/graph");
  // Built-in: per-item shards are small, SLAM gets the memory a floor needs.
  auto o = JobOptions(feats, {}, {});
  EXPECT_EQ(o["mem"], "4G");
  EXPECT_EQ(o["time"], "04:00:00");
  EXPECT_EQ(o["cpus-per-task"], "2");
  o = JobOptions(poses, {}, {});
  EXPECT_EQ(o["mem"], "16G");
  EXPECT_EQ(o["time"], "24:00:00");
  // The graph: node beats stage id beats kind beats default, whatever the order written.
  const std::vector<SchedulerSetting> graph = {Opt("feats:mem=5G"), Opt("features/sift:mem=6G"),
                                               Opt("features:mem=7G"), Opt("default:mem=8G"),
                                               Opt("default:partition=cpu")};
  o = JobOptions(feats, graph, {});
  EXPECT_EQ(o["mem"], "5G");
  EXPECT_EQ(o["partition"], "cpu");
  o = JobOptions(poses, graph, {});
  EXPECT_EQ(o["mem"], "8G");  // the graph's default over the built-in kind's
  // The command line over the graph, even a less specific selector.
  o = JobOptions(feats, graph, {Opt("mem=9G"), Opt("partition=gpu")});
  EXPECT_EQ(o["mem"], "9G");
  EXPECT_EQ(o["partition"], "gpu");
  o = JobOptions(feats, graph, {Opt("feats:mem=10G"), Opt("mem=9G")});
  EXPECT_EQ(o["mem"], "10G");
}

TEST_F(SchedulerSettings, RefusesUnknownSelectorsReservedAndMalformedOptions) {
  Diagnostics errors;
  CheckSchedulerSettings({Opt("feats:mem=4G"), Opt("features:time=1"), Opt("slam/graph:mem=1G"),
                          Opt("partition=cpu"), Opt("cpus-per-task=4")},
                         Graph(), &errors);
  EXPECT_TRUE(errors.empty()) << errors.front().ToString();
  CheckSchedulerSettings({Opt("feat:mem=4G"), Opt("array=0-3"), Opt("Mem=4G"),
                          Opt("cpus-per-task=0"), Opt("dependency=afterok:1")},
                         Graph(), &errors);
  ASSERT_EQ(errors.size(), 5u);
  EXPECT_NE(errors[0].ToString().find("--slurm-opt feat:mem=4G: error: slurm: 'feat' selects no "
                                      "node (did you mean 'feats'?)"),
            std::string::npos)
      << errors[0].ToString();
  EXPECT_NE(errors[1].message.find("'array' is set by locforge"), std::string::npos);
  EXPECT_NE(errors[2].message.find("not an sbatch long option name"), std::string::npos);
  EXPECT_NE(errors[3].message.find("cpus-per-task expects 1 to 4096"), std::string::npos);
  EXPECT_NE(errors[4].message.find("'dependency' is set by locforge"), std::string::npos);
}

TEST(Process, RunsArgvWithoutAShell) {
  // A shell would expand these; an argument vector passes them as they are.
  const ProcessResult r = RunProcess({"printf", "%s|%s", "$HOME; echo x", "*"});
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.out, "$HOME; echo x|*");
  const ProcessResult missing = RunProcess({"locforge-no-such-program-here"});
  EXPECT_FALSE(missing.started);
  EXPECT_NE(missing.error.find("locforge-no-such-program-here"), std::string::npos);
  const ProcessResult failing = RunProcess({"sh", "-c", "echo oops >&2; exit 3"});
  EXPECT_EQ(failing.exit_code, 3);
  EXPECT_EQ(failing.err, "oops\n");
  const ProcessResult slow = RunProcess({"sleep", "30"}, 0.5);
  EXPECT_TRUE(slow.timed_out);
  EXPECT_FALSE(slow.ok());
}

TEST(Usage, MeasuresCpuAndPeakOfTheWorkBetween) {
  // 200 MB touched inside the measured span: the peak covers it, the CPU
  // time covers the work (both in this process).
  const UsageMeter meter;
  std::vector<char> block(200u << 20);
  for (size_t i = 0; i < block.size(); i += 4096) block[i] = static_cast<char>(i);
  volatile double x = 0;
  for (int i = 0; i < 20000000; ++i) x = x + i * 1e-9;
  const Usage used = meter.Stop();
  EXPECT_GE(used.peak_rss_bytes, 200u << 20);
  EXPECT_GT(used.cpu_seconds, 0.005);
  block = {};
  block.shrink_to_fit();
  // A later span starts from the current resident size, not the old peak.
  const UsageMeter next;
  const Usage small = next.Stop();
  if (small.peak_exact) {
    EXPECT_LT(small.peak_rss_bytes, used.peak_rss_bytes - (100u << 20));
  }
}

}  // namespace
}  // namespace locforge::host

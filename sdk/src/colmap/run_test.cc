#include "locforge/colmap/run.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <chrono>
#include <fstream>
#include <thread>

#include "locforge/error.h"
#include "locforge/fs.h"
#include "testing.h"

namespace locforge::colmap {
namespace {

namespace fs = std::filesystem;

std::string ErrorOf(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "no error";
}

class RunColmapTest : public ::testing::Test {
 protected:
  void SetUp() override {
    tmp_ = testing::MakeTempDir("colmap_run");
    options_.log_file = tmp_ / "logs/colmap.log";
  }
  void TearDown() override { fs::remove_all(tmp_); }
  // A stand-in `colmap` (a shell script) to test the runner without COLMAP.
  std::string FakeColmap(const std::string& body) {
    const fs::path p = tmp_ / "fake_colmap";
    WriteFileAtomic(p, "#!/bin/sh\n" + body + "\n");
    ::chmod(p.c_str(), 0755);
    return p.string();
  }
  fs::path tmp_;
  RunOptions options_;
};

TEST_F(RunColmapTest, MissingExecutableSaysSo) {
  options_.executable = (tmp_ / "no/such/colmap").string();
  const std::string e = ErrorOf([&] { RunColmap({"help"}, options_); });
  EXPECT_NE(e.find("colmap executable not found"), std::string::npos) << e;
  EXPECT_NE(e.find("LOCFORGE_COLMAP"), std::string::npos) << e;
  RunOptions no_log;
  EXPECT_NE(ErrorOf([&] { RunColmap({"help"}, no_log); }).find("log_file"), std::string::npos);
}

TEST_F(RunColmapTest, ArgumentsPassVerbatimNoShellAndOutputIsLogged) {
  options_.executable = FakeColmap("pwd; for a in \"$@\"; do echo \"[$a]\"; done; echo oops >&2");
  options_.working_dir = tmp_;
  RunColmap({"feature_extractor", "--image_path", "a dir/with 'quotes'", "$(rm -rf /)", "*"},
            options_);
  const std::string log = ReadFile(options_.log_file);
  EXPECT_NE(log.find(fs::canonical(tmp_).string() + "\n"), std::string::npos) << log;
  EXPECT_NE(log.find("[a dir/with 'quotes']\n[$(rm -rf /)]\n[*]\n"), std::string::npos) << log;
  EXPECT_NE(log.find("oops\n"), std::string::npos) << log;
}

TEST_F(RunColmapTest, FailureReportsStatusAndColmapsErrorLines) {
  options_.executable = FakeColmap(
      "echo 'Reading images'; echo 'I20261122 04:00:00.1 1 a.cc:1] fine';"
      "echo 'F20261122 04:00:00.2 1 reconstruction.cc:743] Check failed: ExistsDir(path)' >&2;"
      "echo '*** Check failure stack trace: ***' >&2; echo '    @ 0x1 main' >&2; exit 3");
  const std::string e = ErrorOf([&] { RunColmap({"model_analyzer", "--path", "x"}, options_); });
  EXPECT_NE(e.find("exit status 3"), std::string::npos) << e;
  EXPECT_NE(e.find("model_analyzer --path x"), std::string::npos) << e;
  EXPECT_NE(e.find("Check failed: ExistsDir(path)"), std::string::npos) << e;
  EXPECT_EQ(e.find("@ 0x1"), std::string::npos) << e;
  EXPECT_NE(e.find(options_.log_file.string()), std::string::npos) << e;
}

TEST_F(RunColmapTest, TimeoutKillsTheChild) {
  options_.executable = FakeColmap("while :; do :; done");  // builtins only: no PATH needed
  options_.timeout_s = 0.3;
  const std::string e = ErrorOf([&] { RunColmap({}, options_); });
  EXPECT_NE(e.find("timed out"), std::string::npos) << e;
}

// True while `pid` is a live (not zombie) process.
bool Alive(pid_t pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(stat, line)) return false;
  const size_t paren = line.rfind(')');
  return paren != std::string::npos && paren + 2 < line.size() && line[paren + 2] != 'Z';
}

TEST_F(RunColmapTest, CancelStopsTheChildAndItsChildren) {
  // colmap stand-in with a child of its own (as a shell pipeline would have).
  const fs::path pid_file = tmp_ / "grandchild.pid";
  options_.executable =
      FakeColmap("sleep 60 & echo $! > '" + pid_file.string() + "'; wait");
  const auto start = std::chrono::steady_clock::now();
  options_.cancelled = [&] {
    return fs::exists(pid_file) && std::chrono::steady_clock::now() - start > std::chrono::milliseconds(300);
  };
  EXPECT_THROW(RunColmap({"feature_extractor"}, options_), Cancelled);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, 10.0);  // stopped, not waited for (the child sleeps 60 s)
  const pid_t grandchild = std::stoi(ReadFile(pid_file));
  for (int i = 0; i < 50 && Alive(grandchild); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_FALSE(Alive(grandchild)) << "pid " << grandchild;
}

TEST_F(RunColmapTest, FindsColmapThroughTheEnvironment) {
  const std::string fake = FakeColmap("exit 0");
  ::setenv("LOCFORGE_COLMAP", fake.c_str(), 1);
  EXPECT_EQ(FindColmapExecutable(), fake);
  EXPECT_EQ(RunColmap({}, options_).executable, fake);
  ::setenv("LOCFORGE_COLMAP", (tmp_ / "nope").c_str(), 1);
  EXPECT_NE(ErrorOf([&] { RunColmap({}, options_); }).find("not found at LOCFORGE_COLMAP="),
            std::string::npos);
  ::unsetenv("LOCFORGE_COLMAP");
}

TEST_F(RunColmapTest, RealColmapFailureCarriesItsMessage) {
  if (FindColmapExecutable().empty()) GTEST_SKIP() << "colmap executable not available";
  const std::string e = ErrorOf(
      [&] { RunColmap({"model_analyzer", "--path", (tmp_ / "absent").string()}, options_); });
  EXPECT_NE(e.find("colmap failed"), std::string::npos) << e;
  EXPECT_NE(e.find("files do not exist"), std::string::npos) << e;
}

}  // namespace
}  // namespace locforge::colmap

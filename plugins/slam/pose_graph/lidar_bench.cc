// locforge_lidar_bench: throughput of the LiDAR half (lidar/preprocess +
// slam/pose_graph) against the duration of the recording, per step, at 1 and
// 2 threads, in one run (the host, the plugins and the graph as a user runs
// them; every run in a fresh workspace, so nothing is cached).
//   locforge_lidar_bench                     # simulates `small` (seed 0, images off) first
//   locforge_lidar_bench --recording DIR --threads 1,2 --keep W
#include <sys/resource.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "keyframes.h"
#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"

namespace {

using namespace locforge;

std::string Quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

int Run(const std::vector<std::string>& args, const fs::path& log) {
  std::string cmd = Quote(LOCFORGE_BENCH_HOST);
  for (const auto& a : args) cmd += " " + Quote(a);
  cmd += " > " + Quote(log.string()) + " 2>&1";
  return std::system(cmd.c_str());
}

double ManifestSeconds(const fs::path& node) {
  return YAML::LoadFile((fs::canonical(node) / ".locforge-complete").string())["seconds"].as<double>();
}

// CPU seconds (user + system) of every child process that has ended.
double ChildrenCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_CHILDREN, &u);
  return u.ru_utime.tv_sec + u.ru_utime.tv_usec * 1e-6 + u.ru_stime.tv_sec + u.ru_stime.tv_usec * 1e-6;
}

void Usage() {
  std::cout << "Usage: locforge_lidar_bench [--recording DIR] [--threads 1,2] [--keep DIR]\n\n"
               "Runs lidar/preprocess + slam/pose_graph (the defaults of configs/gt/lidar.yaml) on a recording,\n"
               "once per thread count, each in a fresh workspace, and prints the seconds of every step against\n"
               "the recording's duration (x real time = recording seconds / processing seconds). Without\n"
               "--recording, the simulator's `small` preset (seed 0, images off) is simulated first.\n";
}

}  // namespace

int main(int argc, char** argv) {
  std::string recording, keep;
  std::vector<int> threads = {1, 2};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      Usage();
      return 0;
    }
    if (i + 1 >= argc) {
      Usage();
      return 2;
    }
    if (a == "--recording") {
      recording = argv[++i];
    } else if (a == "--keep") {
      keep = argv[++i];
    } else if (a == "--threads") {
      threads.clear();
      std::stringstream s(argv[++i]);
      for (std::string t; std::getline(s, t, ',');) threads.push_back(std::stoi(t));
    } else {
      Usage();
      return 2;
    }
  }
  const fs::path dir = keep.empty() ? fs::temp_directory_path() / ("locforge_lidar_bench_" + std::to_string(::getpid()))
                                    : fs::path(keep);
  fs::create_directories(dir);
  if (recording.empty()) {
    std::ofstream(dir / "sim.yaml") << "locforge: 1\nnodes:\n  recording:\n    stage: source/simulator\n"
                                       "    params: {preset: small, seed: 0, cameras: false, masks: false, "
                                       "validation_sequences: 0, test_sequences: 0}\n";
    std::cout << "simulating small (seed 0, images off) ...\n" << std::flush;
    if (Run({"run", (dir / "sim.yaml").string(), "--workspace", (dir / "sim").string()}, dir / "sim.log") != 0) {
      std::cerr << "simulation failed: " << (dir / "sim.log").string() << "\n";
      return 1;
    }
    recording = fs::canonical(dir / "sim/nodes/recording").string();
  }
  // The recording's duration: per sequence, its first to its last LiDAR scan.
  std::map<std::string, std::pair<Timestamp, Timestamp>> spans;
  size_t scans = 0;
  {
    kapture::Kapture k(recording);
    std::set<Timestamp> seen;
    for (const auto& r : k.ReadDataRecords(kapture::kSensorLidar)) {
      const std::string seq = lidar::SequenceOfScan(r.path);
      auto [it, inserted] = spans.emplace(seq, std::make_pair(r.timestamp, r.timestamp));
      it->second.first = std::min(it->second.first, r.timestamp);
      it->second.second = std::max(it->second.second, r.timestamp);
      if (seen.insert(r.timestamp).second) ++scans;
    }
  }
  double duration = 0;
  for (const auto& [seq, span] : spans) duration += (span.second - span.first) * 1e-6 + 0.1;
  std::ofstream(dir / "lidar.yaml") << "locforge: 1\nvars: {dataset: \"\"}\nnodes:\n"
                                       "  scans:\n    stage: lidar/preprocess\n    params: {dataset: \"${dataset}\"}\n"
                                       "  slam:\n    stage: slam/pose_graph\n    inputs: {scans: scans.scans}\n"
                                       "    params: {dataset: \"${dataset}\"}\n";
  std::vector<std::string> steps;
  std::map<int, std::map<std::string, double>> seconds;  // threads -> step -> s
  for (int t : threads) {
    const fs::path ws = dir / ("ws_t" + std::to_string(t));
    fs::remove_all(ws);
    std::cout << "LiDAR half with " << t << " thread(s) ...\n" << std::flush;
    const double cpu_before = ChildrenCpuSeconds();
    if (Run({"run", (dir / "lidar.yaml").string(), "--workspace", ws.string(), "--set", "dataset=" + recording,
             "--threads", std::to_string(t)},
            dir / ("run_t" + std::to_string(t) + ".log")) != 0) {
      std::cerr << "the LiDAR half failed: " << (dir / ("run_t" + std::to_string(t) + ".log")).string() << "\n";
      return 1;
    }
    auto& s = seconds[t];
    s["preprocess"] = ManifestSeconds(ws / "nodes/scans");
    const YAML::Node slam = YAML::LoadFile((ws / "nodes/slam/slam.json").string());
    for (const auto& kv : slam["step_seconds"]) {
      const std::string name = "slam: " + kv.first.as<std::string>();
      s[name] = kv.second.as<double>();
      if (std::find(steps.begin(), steps.end(), name) == steps.end()) steps.push_back(name);
    }
    s["slam (node)"] = ManifestSeconds(ws / "nodes/slam");
    s["LiDAR half"] = s["preprocess"] + s["slam (node)"];
    // The host process's CPU (all its threads): a machine shared with other
    // work inflates the wall times above but hardly this.
    s["LiDAR half, CPU (user+sys)"] = ChildrenCpuSeconds() - cpu_before;
  }
  std::vector<std::string> rows = {"preprocess"};
  rows.insert(rows.end(), steps.begin(), steps.end());
  rows.push_back("slam (node)");
  rows.push_back("LiDAR half");
  rows.push_back("LiDAR half, CPU (user+sys)");
  std::printf("\nrecording: %s\n%zu scans, %zu sequences, %.1f s of recording\n\n", recording.c_str(), scans,
              spans.size(), duration);
  std::printf("%-26s", "step");
  for (int t : threads) std::printf(" | %3d thr: s | scans/s | x real", t);
  std::printf("\n");
  for (const auto& r : rows) {
    std::printf("%-26s", r.c_str());
    for (int t : threads) {
      const double s = seconds[t].count(r) ? seconds[t][r] : 0;
      std::printf(" | %10.2f | %7.1f | %6.2f", s, s > 0 ? scans / s : 0.0, s > 0 ? duration / s : 0.0);
    }
    std::printf("\n");
  }
  if (keep.empty()) fs::remove_all(dir);
  return 0;
}

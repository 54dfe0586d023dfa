// `locforge status WORKSPACE`: per-node state and cost. With a Slurm
// submission: the latest one's nodes, from squeue/sacct and the workspace;
// without: the nodes linked in WORKSPACE/nodes (and variants/*/nodes).
// `--verify`: every complete node folder hashed against its file list.
#include <unistd.h>

#include <algorithm>
#include <iostream>

#include "cli.h"
#include "executor.h"
#include "locforge/params.h"
#include "output_files.h"
#include "slurm.h"

namespace locforge::host {

namespace {

const char kStatusHelp[] = R"(Usage: locforge status WORKSPACE [--wait] [--poll SECONDS]
       locforge status WORKSPACE --verify

Shows each node of the workspace: state, items, wall-clock and CPU seconds,
peak memory, output size and shards (from the node folders' manifests).

After `locforge run ... --executor slurm`, the nodes of the latest submission
(WORKSPACE/slurm/latest), their states from squeue (and sacct when the
cluster keeps accounting) and the workspace: cached, pending (reason),
running (shards done/running), done, failed (the job, shard and log file),
blocked (an input failed). Without a submission, the nodes linked in
WORKSPACE/nodes and WORKSPACE/variants/*/nodes.

Options:
  --wait            Follow the submission until no job is queued or running
                    (Ctrl-C stops following; the jobs go on)
  --poll SECONDS    Interval between squeue calls with --wait (default 10)
  --verify          Hash every output file of every complete node folder of
                    WORKSPACE/cache and compare it with the list its run
                    recorded (size and SHA-256); list each damaged folder with
                    its missing, resized or changed files. (A run checks the
                    folders it serves by size only; this reads every byte.)

Exit codes: 0 ok, 1 a job failed (with --wait, or already failed) or --verify
found a damaged folder, 2 bad usage.
)";

// Rows of the nodes linked in the workspace (a local run's, or Slurm's once done).
std::vector<NodeState> LinkedNodes(const Workspace& workspace) {
  std::vector<NodeState> out;
  auto add = [&](const std::string& variant, const fs::path& nodes) {
    std::error_code ec;
    std::vector<fs::path> links;
    for (fs::directory_iterator it(nodes, ec), end; !ec && it != end; it.increment(ec))
      links.push_back(it->path());
    std::sort(links.begin(), links.end());
    for (const auto& link : links) {
      NodeState s;
      s.job.job_id = "-";
      s.job.variant = variant;
      s.job.node = link.filename().string();
      const fs::path dir = fs::weakly_canonical(link, ec);
      if (!Workspace::IsComplete(dir)) {
        s.state = "missing";
      } else {
        s.state = "done";
        try {
          s.manifest = ReadManifest(dir);
          s.has_manifest = true;
          s.job.stage = s.manifest.stage;
        } catch (const std::exception& e) {
          s.detail = e.what();
        }
      }
      out.push_back(s);
    }
  };
  add("", workspace.root() / "nodes");
  std::error_code ec;
  for (fs::directory_iterator it(workspace.root() / "variants", ec), end; !ec && it != end;
       it.increment(ec))
    add(it->path().filename().string(), it->path() / "nodes");
  return out;
}

// "features" of cache/features-0123456789abcdef.
std::string NodeOfFolder(const fs::path& dir) {
  const std::string name = dir.filename().string();
  return name.size() > 17 && name[name.size() - 17] == '-' ? name.substr(0, name.size() - 17) : name;
}

// Checks every complete node folder of cache/ against its file list, contents
// hashed; prints each damaged one with its files. Returns the exit code.
int VerifyWorkspace(const Workspace& workspace) {
  std::vector<fs::path> folders;
  std::error_code ec;
  const fs::path cache = workspace.root() / "cache";
  for (fs::directory_iterator it(cache, ec), end; !ec && it != end; it.increment(ec))
    if (Workspace::IsComplete(it->path())) folders.push_back(it->path());
  std::sort(folders.begin(), folders.end());
  uint64_t files = 0, bytes = 0;
  size_t damaged = 0, unverifiable = 0;
  for (const fs::path& dir : folders) {
    const FolderCheck check = CheckNodeFolder(dir, true);
    files += check.files;
    bytes += check.bytes_hashed;
    const std::string name = "cache/" + dir.filename().string();
    if (!check.verifiable) {
      ++unverifiable;
      std::cout << "unverifiable " << name << " (node " << NodeOfFolder(dir)
                << "): its manifest lists no output files (an older run's)\n";
    } else if (!check.ok()) {
      ++damaged;
      std::cout << "damaged " << name << " (node " << NodeOfFolder(dir) << "):\n";
      for (const std::string& d : check.damage) std::cout << "  " << d << "\n";
    }
  }
  std::cout << "verified " << folders.size() << " node folders, " << files << " files, "
            << FormatBytes(bytes) << " hashed: " << damaged << " damaged, " << unverifiable
            << " unverifiable\n";
  return damaged > 0 ? 1 : 0;
}

}  // namespace

int StatusCommand(const Args& args) {
  if (WantsHelp(args)) {
    std::cout << kStatusHelp;
    return 0;
  }
  std::string dir;
  bool wait = false, verify = false;
  double poll = 10;
  try {
    for (size_t i = 0; i < args.size(); ++i) {
      std::string v;
      if (args[i] == "--wait") {
        wait = true;
      } else if (args[i] == "--verify") {
        verify = true;
      } else if (TakeOption(args, &i, "--poll", &v)) {
        int64_t n = 0;
        if (!ParseInt(v, &n) || n < 1 || n > 3600)
          return UsageError("status", "--poll expects seconds from 1 to 3600, got '" + v + "'");
        poll = static_cast<double>(n);
      } else if (args[i].rfind("-", 0) == 0) {
        const std::string hint = DidYouMean(args[i], {"--wait", "--poll", "--verify", "--help"});
        return UsageError("status", "unknown option '" + args[i] + "'" +
                                        (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
      } else if (dir.empty()) {
        dir = args[i];
      } else {
        return UsageError("status", "unexpected argument '" + args[i] + "'");
      }
    }
  } catch (const std::invalid_argument& e) {
    return UsageError("status", e.what());
  }
  if (dir.empty()) return UsageError("status", "expected a workspace folder");
  std::error_code ec;
  if (!fs::is_directory(fs::path(dir) / "cache", ec)) {
    std::cerr << "locforge status: " << dir << " is not a workspace (no cache/ folder)\n";
    return 2;
  }
  const Workspace workspace(dir);
  if (verify) {
    if (wait) return UsageError("status", "--verify and --wait do not go together");
    return VerifyWorkspace(workspace);
  }
  const bool slurm = fs::is_regular_file(workspace.root() / "slurm" / "latest", ec);
  if (!slurm) {
    if (wait) return UsageError("status", "--wait follows a Slurm submission; " + dir + " has none");
    std::cout << FormatSlurmStatus(LinkedNodes(workspace));
    return 0;
  }
  Submission sub;
  try {
    sub = ReadLatestSubmission(workspace);
  } catch (const std::exception& e) {
    std::cerr << "locforge status: " << e.what() << "\n";
    return 2;
  }
  std::vector<NodeState> states;
  if (wait) {
    Reporter reporter(std::cerr, ::isatty(STDERR_FILENO) != 0);
    bool cancelled = false;
    states = WaitForSlurm(workspace, sub, poll, nullptr, reporter, &cancelled);
  } else {
    states = QuerySlurmStatus(workspace, sub);
  }
  std::cout << "submission: " << sub.file.string() << "\n" << FormatSlurmStatus(states);
  int rc = 0;
  for (const auto& s : states) {
    for (const auto& f : s.failures) std::cerr << "error: " << f << "\n";
    if (s.state == "failed" || s.state == "lost" || (wait && s.state != "done" && s.state != "cached"))
      rc = 1;
  }
  return rc;
}

}  // namespace locforge::host

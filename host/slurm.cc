#include "slurm.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>
#include <thread>

#include "executor.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/params.h"
#include "output_files.h"
#include "process.h"

namespace locforge::host {

namespace {

// sbatch options locforge sets for every job itself.
const std::set<std::string> kReservedOptions = {
    "array",  "dependency", "output", "error",  "job-name", "parsable", "wrap",
    "chdir",  "kill-on-invalid-dep",  "export", "input",    "open-mode", "wait"};

// Built-in requests per stage kind: (selector, option, value). The figures
// come from the measured costs of docs/results/cost-model.md: shards of
// per-item stages stay under 2 GB; the whole-set stages that do not shard
// (SLAM, triangulation, the bundle adjustment) get the memory and time a
// floor needs.
struct Default {
  const char* selector;
  bool per_item_only;  // applies to per-item nodes only
  const char* key;
  const char* value;
};
const Default kDefaults[] = {
    {"default", false, "cpus-per-task", "2"},
    {"default", false, "mem", "8G"},
    {"default", false, "time", "12:00:00"},
    {"default", true, "mem", "4G"},
    {"default", true, "time", "04:00:00"},
    {"slam", false, "mem", "16G"},
    {"slam", false, "time", "24:00:00"},
    {"mapper", false, "mem", "32G"},
    {"mapper", false, "time", "24:00:00"},
    {"gt", false, "cpus-per-task", "8"},
    {"gt", false, "mem", "64G"},
    {"gt", false, "time", "48:00:00"},
    {"pipeline", false, "cpus-per-task", "8"},
    {"pipeline", false, "mem", "32G"},
    {"pipeline", false, "time", "48:00:00"},
};

std::string KindOf(const ResolvedNode& node) {
  return node.stage->id.substr(0, node.stage->id.find('/'));
}

bool IsOptionName(const std::string& key) {
  if (key.empty() || !std::islower(static_cast<unsigned char>(key[0]))) return false;
  for (char c : key)
    if (!(std::islower(static_cast<unsigned char>(c)) || std::isdigit(static_cast<unsigned char>(c)) ||
          c == '-'))
      return false;
  return true;
}

// 0 default, 1 kind, 2 kind/name, 3 node; -1 when it does not select `node`.
int Specificity(const std::string& selector, const ResolvedNode& node) {
  if (selector == "default") return 0;
  if (selector == KindOf(node)) return 1;
  if (selector == node.stage->id) return 2;
  if (selector == node.name) return 3;
  return -1;
}

void Apply(const std::vector<SchedulerSetting>& settings, const ResolvedNode& node,
           std::map<std::string, std::string>* out) {
  for (int level = 0; level <= 3; ++level)
    for (const auto& s : settings)
      if (Specificity(s.selector, node) == level) (*out)[s.key] = s.value;
}

std::vector<std::string> Split(const std::string& text, char sep) {
  std::vector<std::string> out;
  std::string cur;
  std::istringstream in(text);
  while (std::getline(in, cur, sep)) out.push_back(cur);
  if (!text.empty() && text.back() == sep) out.push_back("");
  return out;
}

std::string Join(const std::vector<std::string>& parts, const std::string& sep) {
  std::string out;
  for (const auto& p : parts) out += (out.empty() ? "" : sep) + p;
  return out;
}

// "0-2" for consecutive indices, else "0,2,5".
std::string ArraySpec(const std::vector<int>& indices) {
  bool consecutive = true;
  for (size_t i = 1; i < indices.size(); ++i) consecutive &= indices[i] == indices[i - 1] + 1;
  if (consecutive && indices.size() > 1)
    return std::to_string(indices.front()) + "-" + std::to_string(indices.back());
  std::vector<std::string> parts;
  for (int i : indices) parts.push_back(std::to_string(i));
  return Join(parts, ",");
}

std::vector<int> ParseArraySpec(const std::string& spec) {
  std::vector<int> out;
  for (const auto& part : Split(spec, ',')) {
    if (part.empty()) continue;
    const size_t dash = part.find('-');
    try {
      if (dash == std::string::npos) {
        out.push_back(std::stoi(part));
      } else {
        for (int i = std::stoi(part.substr(0, dash)); i <= std::stoi(part.substr(dash + 1)); ++i)
          out.push_back(i);
      }
    } catch (const std::exception&) {
    }
  }
  return out;
}

const char kJobScript[] =
    "#!/bin/sh\n"
    "# Written by locforge: runs the job's command, given as sbatch's arguments\n"
    "# after this script (nothing of it is parsed by a shell).\n"
    "exec \"$@\"\n";

// Log file of one task: %A/%a/%j replaced.
std::string TaskLog(const SlurmJob& job, const std::string& task) {
  std::string log = job.log;
  auto replace = [&log](const std::string& from, const std::string& to) {
    for (size_t p = log.find(from); p != std::string::npos; p = log.find(from, p + to.size()))
      log.replace(p, from.size(), to);
  };
  replace("%A", job.job_id);
  replace("%a", task);
  replace("%j", job.job_id);
  return log;
}

bool IsActive(const std::string& state) {
  return state == "PENDING" || state == "RUNNING" || state == "CONFIGURING" ||
         state == "COMPLETING" || state == "SUSPENDED" || state == "REQUEUED" ||
         state == "REQUEUE_HOLD" || state == "REQUEUE_FED" || state == "RESIZING" ||
         state == "SIGNALING" || state == "STAGE_OUT" || state == "STOPPED" ||
         state == "RESV_DEL_HOLD";
}

struct TaskState {
  std::string state;   // Slurm's (PENDING, RUNNING, COMPLETED, FAILED, CANCELLED, ...)
  std::string reason;  // squeue's reason (pending jobs)
};

// States of the given jobs' tasks, keyed "ID" (single job) or "ID_TASK".
std::map<std::string, TaskState> SlurmStates(const std::set<std::string>& ids) {
  std::map<std::string, TaskState> out;
  if (ids.empty()) return out;
  // Every job of this user, one array task a line, finished ones included
  // while the controller keeps them (MinJobAge).
  const ProcessResult q = RunProcess({"squeue", "--noheader", "--array", "--states=all",
                                      "--user=" + std::to_string(::getuid()),
                                      "--format=%F|%K|%T|%r"},
                                     60);
  if (q.ok()) {
    std::istringstream lines(q.out);
    std::string line;
    while (std::getline(lines, line)) {
      const auto f = Split(line, '|');
      if (f.size() < 4 || !ids.count(f[0])) continue;
      const bool array = f[1] != "N/A" && !f[1].empty();
      out[array ? f[0] + "_" + f[1] : f[0]] = {f[2], f[3]};
    }
  }
  // Jobs the controller forgot: accounting, when the cluster keeps it.
  std::vector<std::string> missing;
  for (const auto& id : ids) {
    bool seen = false;
    for (const auto& [key, st] : out) seen |= key == id || key.rfind(id + "_", 0) == 0;
    if (!seen) missing.push_back(id);
  }
  if (!missing.empty()) {
    const ProcessResult a = RunProcess({"sacct", "--noheader", "--parsable2", "--allocations",
                                        "--jobs=" + Join(missing, ","), "--format=JobID,State"},
                                       60);
    if (a.ok()) {
      std::istringstream lines(a.out);
      std::string line;
      while (std::getline(lines, line)) {
        const auto f = Split(line, '|');
        if (f.size() < 2 || f[0].empty()) continue;
        const std::string state = f[1].substr(0, f[1].find(' '));  // "CANCELLED by 0"
        if (!out.count(f[0])) out[f[0]] = {state, ""};
      }
    }
  }
  return out;
}

std::string Seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f", s);
  return buf;
}

}  // namespace

bool SlurmOptions::Check(std::string* why) const {
  if (shards < 1 || shards > 100000) {
    *why = "--shards expects 1 to 100000";
    return false;
  }
  if (graph.empty() || !graph.is_absolute()) {
    *why = "the graph path must be absolute";
    return false;
  }
  if (locforge.empty()) {
    *why = "the locforge executable is unknown";
    return false;
  }
  return true;
}

bool ParseSchedulerSetting(const std::string& text, SchedulerSetting* out) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos) return false;
  std::string lhs = text.substr(0, eq);
  out->value = text.substr(eq + 1);
  const size_t colon = lhs.find(':');
  out->selector = colon == std::string::npos ? "default" : lhs.substr(0, colon);
  out->key = colon == std::string::npos ? lhs : lhs.substr(colon + 1);
  out->where = {"--slurm-opt " + text};
  return !out->key.empty() && !out->selector.empty();
}

void CheckSchedulerSettings(const std::vector<SchedulerSetting>& settings,
                            const std::vector<ResolvedGraph>& variants, Diagnostics* errors) {
  std::set<std::string> selectors = {"default"};
  for (const auto& g : variants)
    for (const auto& n : g.nodes) selectors.insert({n.name, KindOf(n), n.stage->id});
  const std::vector<std::string> names(selectors.begin(), selectors.end());
  for (const auto& s : settings) {
    if (!selectors.count(s.selector))
      errors->push_back({s.where, "slurm: '" + s.selector + "' selects no node" +
                                      Hint(s.selector, names) +
                                      "; expected default, a stage kind, a stage id or a node "
                                      "of the graph"});
    if (!IsOptionName(s.key))
      errors->push_back({s.where, "slurm: '" + s.key +
                                      "' is not an sbatch long option name (expected e.g. "
                                      "cpus-per-task, mem, time, partition)"});
    else if (kReservedOptions.count(s.key))
      errors->push_back({s.where, "slurm: '" + s.key +
                                      "' is set by locforge for each job; it cannot be chosen"});
    if (s.value.empty() || s.value.find('\n') != std::string::npos)
      errors->push_back({s.where, "slurm: '" + s.key + "' needs a one-line, non-empty value"});
    if (s.key == "cpus-per-task") {
      int64_t n = 0;
      if (!ParseInt(s.value, &n) || n < 1 || n > 4096)
        errors->push_back({s.where, "slurm: cpus-per-task expects 1 to 4096, got '" + s.value + "'"});
    }
  }
}

std::map<std::string, std::string> JobOptions(const ResolvedNode& node,
                                              const std::vector<SchedulerSetting>& graph,
                                              const std::vector<SchedulerSetting>& cli) {
  std::map<std::string, std::string> out;
  const bool per_item = node.stage->per_item();
  for (int level = 0; level <= 1; ++level)
    for (const auto& d : kDefaults)
      if ((level == 0 ? std::string(d.selector) == "default"
                      : std::string(d.selector) == KindOf(node)) &&
          (!d.per_item_only || per_item))
        out[d.key] = d.value;
  Apply(graph, node, &out);
  Apply(cli, node, &out);
  return out;
}

namespace {

// The workspace's slurm/ folder with the job script (rewritten only when it
// changed), and logs/slurm/.
fs::path PrepareSlurmFolders(const Workspace& workspace) {
  const fs::path slurm_dir = workspace.root() / "slurm";
  fs::create_directories(slurm_dir);
  fs::create_directories(workspace.root() / "logs" / "slurm");
  const fs::path script = slurm_dir / "job.sh";
  if (!fs::exists(script) || ReadFile(script) != kJobScript) {
    WriteFileAtomic(script, kJobScript);
    fs::permissions(script, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                                fs::perms::others_read | fs::perms::others_exec);
  }
  return slurm_dir;
}

// A new submission-<UTC time>[-N].tsv in slurm_dir.
fs::path NewRecordPath(const fs::path& slurm_dir) {
  const std::string stamp = UtcNow(true);
  fs::path record = slurm_dir / ("submission-" + stamp + ".tsv");
  for (int i = 1; fs::exists(record); ++i)
    record = slurm_dir / ("submission-" + stamp + "-" + std::to_string(i) + ".tsv");
  return record;
}

// The submission record (and slurm/latest pointing to it).
void WriteRecord(const Submission& sub) {
  std::string text = "# locforge Slurm submission: job\tvariant\tnode\tstage\tkey16\tshards\tarray\tlog\tafter\n";
  for (const auto& j : sub.jobs)
    text += j.job_id + "\t" + j.variant + "\t" + j.node + "\t" + j.stage + "\t" + j.key16 + "\t" +
            std::to_string(j.shards) + "\t" + (j.array.empty() ? "-" : j.array) + "\t" +
            (j.log.empty() ? "-" : j.log) + "\t" + (j.after.empty() ? "-" : j.after) + "\n";
  WriteFileAtomic(sub.file, text);
  WriteFileAtomic(sub.file.parent_path() / "latest", sub.file.filename().string() + "\n");
}

// The shards of a per-item node still to run: those that left no record
// (shards that finished their items are not run again). All done but not
// published (killed while finalizing): none, and one job without --shard
// resumes every item from the journals and finalizes.
std::vector<int> ShardsToRun(const fs::path& dir, int shards, int* job_shards) {
  std::vector<int> indices;
  const auto records = ReadShardRecords(Workspace::PartialDir(dir, true), shards);
  std::set<int> done;
  for (const auto& r : records) done.insert(r.index);
  for (int i = 0; i < shards; ++i)
    if (!done.count(i)) indices.push_back(i);
  if (!indices.empty()) *job_shards = shards;
  return indices;
}

// sbatch's command line for a node's job: the job script running
// `locforge run GRAPH --node NODE` (with its shard of an array).
std::vector<std::string> SbatchCommand(const SlurmJob& job, const std::set<std::string>& after,
                                       const std::map<std::string, std::string>& opts, const fs::path& script,
                                       const SlurmOptions& options, const Workspace& workspace) {
  std::vector<std::string> argv = {"sbatch", "--parsable", "--job-name=lf-" + job.node,
                                   "--output=" + job.log, "--chdir=" + options.cwd.string(),
                                   "--kill-on-invalid-dep=yes"};
  if (!after.empty()) argv.push_back("--dependency=afterok:" + Join({after.begin(), after.end()}, ":"));
  if (job.shards > 1) argv.push_back("--array=" + job.array);
  for (const auto& [k, v] : opts) argv.push_back("--" + k + "=" + v);
  argv.push_back(script.string());
  argv.insert(argv.end(), {options.locforge.string(), "run", options.graph.string(),
                           "--workspace", workspace.root().string()});
  argv.insert(argv.end(), options.forward.begin(), options.forward.end());
  if (!job.variant.empty()) argv.insert(argv.end(), {"--variant", job.variant});
  const auto cpus = opts.find("cpus-per-task");
  argv.insert(argv.end(), {"--node", job.node, "--expect-key", job.key16, "--threads",
                           cpus == opts.end() ? "1" : cpus->second});
  if (job.shards > 1) argv.insert(argv.end(), {"--shard", "array/" + std::to_string(job.shards)});
  return argv;
}

// Runs sbatch: the job id; on failure the record of the jobs so far is
// written and the error says why.
std::string RunSbatch(const std::vector<std::string>& argv, const std::string& node, const Submission& sub,
                      Reporter& reporter) {
  reporter.FileOnly("+ " + DisplayCommand(argv));
  const ProcessResult r = RunProcess(argv, 300);
  std::string id = r.out.substr(0, r.out.find_first_of(";\n"));
  if (r.ok() && !id.empty() && id.find_first_not_of("0123456789") == std::string::npos) return id;
  WriteRecord(sub);
  std::string msg = r.error;
  std::string err = r.err;
  while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
  if (!err.empty()) msg += (msg.empty() ? "" : "; ") + err;
  if (msg.empty()) msg = "unexpected output '" + r.out + "'";
  throw Error("slurm: submitting node '" + node + "' failed: " + msg +
              (r.started ? "" : " (is this a Slurm submit host? sbatch must be on PATH)") +
              (sub.jobs.empty() ? "" : "; jobs submitted so far are listed in " + sub.file.string()));
}

// One submission: the jobs so far, and the job computing each cache key.
struct Submitter {
  const Workspace& workspace;
  const std::vector<SchedulerSetting>& graph_settings;
  const SlurmOptions& options;
  Reporter& reporter;
  fs::path slurm_dir;
  Submission sub;
  std::map<std::string, std::string> job_of_key;  // key -> job id ("-" when complete)

  // A node's line: the job of the same node in an earlier variant (one job
  // computes it for both), "-" when complete, or a new job.
  void Node(const ResolvedGraph& graph, const ResolvedNode& node, const std::map<std::string, std::string>& keys) {
    const std::string& key = keys.at(node.name);
    SlurmJob job;
    job.variant = graph.variant;
    job.node = node.name;
    job.stage = node.stage->id;
    job.key16 = key.substr(0, 16);
    if (auto known = job_of_key.find(key); known != job_of_key.end()) {
      job.job_id = known->second;
      sub.jobs.push_back(job);
      return;
    }
    const fs::path dir = workspace.NodeDir(node.name, key);
    const std::string label = (graph.variant.empty() ? "" : graph.variant + "/") + node.name;
    if (ServableFromCache(workspace, label, dir, reporter)) {
      job.job_id = "-";
      job_of_key[key] = "-";
      workspace.Link(graph.variant, node.name, dir);
      sub.jobs.push_back(job);
      return;
    }
    Submit(node, dir, keys, &job);
  }

  void Submit(const ResolvedNode& node, const fs::path& dir, const std::map<std::string, std::string>& keys,
              SlurmJob* job) {
    const auto opts = JobOptions(node, graph_settings, options.settings);
    std::vector<int> indices;
    if (node.stage->per_item() && options.shards > 1) indices = ShardsToRun(dir, options.shards, &job->shards);
    std::set<std::string> after;
    for (const auto& in : node.inputs) {
      const std::string& id = job_of_key.at(keys.at(in.node));
      if (id != "-") after.insert(id);
    }
    job->after = Join({after.begin(), after.end()}, ",");
    job->array = job->shards > 1 ? ArraySpec(indices) : "";
    const fs::path log_dir = workspace.root() / "logs" / "slurm";
    job->log = (log_dir / (node.name + (job->shards > 1 ? "-%A_%a.log" : "-%j.log"))).string();
    const std::string id = RunSbatch(
        SbatchCommand(*job, after, opts, slurm_dir / "job.sh", options, workspace), node.name, sub, reporter);
    job->job_id = id;
    job_of_key[keys.at(node.name)] = id;
    sub.jobs.push_back(*job);
    reporter.Line("submitted " + (job->variant.empty() ? "" : job->variant + "/") + node.name + ": job " + id +
                  (job->shards > 1 ? " (array " + job->array + " of " + std::to_string(job->shards) + " shards)"
                                   : "") +
                  (after.empty() ? "" : ", after " + job->after));
  }
};

}  // namespace

Submission SubmitToSlurm(const Workspace& workspace, const std::vector<ResolvedGraph>& variants,
                         const std::vector<SchedulerSetting>& graph_settings,
                         const SlurmOptions& options, Reporter& reporter) {
  std::string why;
  if (!options.Check(&why)) throw Error("slurm: " + why);
  Submitter s{workspace, graph_settings, options, reporter, PrepareSlurmFolders(workspace)};
  s.sub.file = NewRecordPath(s.slurm_dir);
  for (const auto& graph : variants) {
    std::map<std::string, std::string> keys;
    for (const auto& node : graph.nodes) {
      const std::string key = CacheKey(node, keys);
      keys[node.name] = key;
      s.Node(graph, node, keys);
    }
  }
  WriteRecord(s.sub);
  return s.sub;
}

Submission ReadSubmission(const fs::path& file) {
  Submission sub;
  sub.file = file;
  std::ifstream in(file);
  if (!in) throw InputError(file.string(), 0, "", "cannot read the submission record");
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty() || line[0] == '#') continue;
    const auto f = Split(line, '\t');
    if (f.size() != 9)
      throw InputError(file.string(), number, "", "expected 9 tab-separated fields, got " +
                                                      std::to_string(f.size()));
    SlurmJob j;
    j.job_id = f[0];
    j.variant = f[1];
    j.node = f[2];
    j.stage = f[3];
    j.key16 = f[4];
    int64_t shards = 1;
    if (!ParseInt(f[5], &shards) || shards < 1)
      throw InputError(file.string(), number, "shards", "expected a positive number");
    j.shards = static_cast<int>(shards);
    j.array = f[6] == "-" ? "" : f[6];
    j.log = f[7] == "-" ? "" : f[7];
    j.after = f[8] == "-" ? "" : f[8];
    sub.jobs.push_back(j);
  }
  return sub;
}

Submission ReadLatestSubmission(const Workspace& workspace) {
  const fs::path latest = workspace.root() / "slurm" / "latest";
  std::error_code ec;
  if (!fs::is_regular_file(latest, ec))
    throw InputError(latest.string(), 0, "",
                     "no Slurm submission in this workspace (run with --executor slurm first)");
  std::string name = ReadFile(latest);
  while (!name.empty() && (name.back() == '\n' || name.back() == ' ')) name.pop_back();
  return ReadSubmission(workspace.root() / "slurm" / name);
}

namespace {

// A line whose node is complete (done, or cached at submission), or whose
// node was complete at submission and is gone: its state; false otherwise.
bool SettledState(const SlurmJob& j, const fs::path& dir, NodeState* s) {
  if (Workspace::IsComplete(dir)) {
    s->state = j.job_id == "-" ? "cached" : "done";
    s->terminal = true;
    try {
      s->manifest = ReadManifest(dir);
      s->has_manifest = true;
    } catch (const std::exception&) {
    }
    return true;
  }
  if (j.job_id != "-") return false;
  s->state = "lost";
  s->detail = "complete at submission, now missing: submit again";
  s->terminal = true;
  return true;
}

// Tasks of a line: one job, or the submitted shards of an array: (state key, shard label).
std::vector<std::pair<std::string, std::string>> TasksOf(const SlurmJob& j) {
  std::vector<std::pair<std::string, std::string>> tasks;
  if (j.shards > 1) {
    for (int i : ParseArraySpec(j.array))
      tasks.push_back({j.job_id + "_" + std::to_string(i), std::to_string(i) + "/" + std::to_string(j.shards)});
  } else {
    tasks.push_back({j.job_id, ""});
  }
  return tasks;
}

struct TaskCounts {
  int running = 0, pending = 0, done = 0, failed = 0, blocked = 0;
  std::string reason;  // why the first pending task waits
};

// One task's Slurm state counted (recorded: the shards that left a record).
void CountTask(const SlurmJob& j, const std::string& key, const std::string& shard,
               const std::map<std::string, TaskState>& states, const std::set<int>& recorded, TaskCounts* c,
               NodeState* s) {
  auto st = states.find(key);
  // A pending array not yet split into tasks is listed under its id.
  if (st == states.end() && j.shards > 1) st = states.find(j.job_id + "_" + j.array);
  std::string state = st == states.end() ? "" : st->second.state;
  const std::string why = st == states.end() ? "" : st->second.reason;
  const int index = shard.empty() ? -1 : std::stoi(shard);
  if (state.empty()) {
    // Gone from the controller and no accounting: the workspace decides.
    state = (index >= 0 && recorded.count(index)) ? "COMPLETED" : "UNKNOWN";
  }
  const std::string label = "node '" + (j.variant.empty() ? "" : j.variant + "/") + j.node + "'" +
                            (shard.empty() ? "" : " shard " + shard) + " (job " + key + ")";
  if (IsActive(state)) {
    if (state == "PENDING" && why.find("DependencyNeverSatisfied") != std::string::npos) {
      ++c->blocked;
      s->active_ids.push_back(key);
      return;
    }
    (state == "PENDING" ? c->pending : c->running)++;
    if (state == "PENDING" && c->reason.empty()) c->reason = why;
    s->active_ids.push_back(key);
  } else if (state == "COMPLETED") {
    if (index >= 0 && !recorded.count(index)) {
      ++c->failed;
      s->failures.push_back(label + " completed without finishing its items; log: " +
                            TaskLog(j, index >= 0 ? std::to_string(index) : ""));
    } else {
      ++c->done;
    }
  } else if (state == "CANCELLED" && (why.find("Dependency") != std::string::npos)) {
    ++c->blocked;
  } else {
    ++c->failed;
    s->failures.push_back(label + " " +
                          (state == "UNKNOWN" ? "ended (no longer known to Slurm) without finishing" : state) +
                          "; log: " + TaskLog(j, index >= 0 ? std::to_string(index) : ""));
  }
}

// The line's state from its tasks' counts (n tasks; input_failed: a job it
// waits on failed, so Slurm cancels it: kill-on-invalid-dep).
void DecideState(const SlurmJob& j, const fs::path& dir, const TaskCounts& c, int n, bool input_failed,
                 NodeState* s) {
  const bool active = c.running + c.pending > 0;
  if (c.failed > 0) {
    s->state = "failed";
  } else if (input_failed && c.done < n) {
    s->state = "blocked";
    s->detail = "an input failed";
  } else if (c.blocked > 0 && !active) {
    s->state = "blocked";
    s->detail = "an input failed";
  } else if (c.running > 0) {
    s->state = "running";
  } else if (c.pending > 0) {
    s->state = "pending";
    s->detail = c.reason;
  } else if (c.done == n) {
    // Every job ended well but the node is not complete: lost output.
    s->state = "failed";
    s->failures.push_back("node '" + j.node + "': its jobs completed but " + dir.string() +
                          " is not complete; log: " + TaskLog(j, j.shards > 1 ? "*" : ""));
  } else {
    s->state = "failed";
  }
  if (j.shards > 1) {
    std::string d = std::to_string(c.done + (j.shards - n)) + "/" + std::to_string(j.shards) + " shards done";
    if (c.running) d += ", " + std::to_string(c.running) + " running";
    if (c.pending) d += ", " + std::to_string(c.pending) + " pending";
    if (c.failed) d += ", " + std::to_string(c.failed) + " failed";
    s->detail = s->detail.empty() ? d : d + "; " + s->detail;
  }
  // Blocked jobs never start: they are cancelled, not waited for.
  s->terminal = c.running == 0 && (c.pending == 0 || s->state == "blocked");
}

}  // namespace

std::vector<NodeState> QuerySlurmStatus(const Workspace& workspace, const Submission& sub) {
  std::set<std::string> ids;
  for (const auto& j : sub.jobs)
    if (j.job_id != "-") ids.insert(j.job_id);
  // Slurm first, then the workspace: a job that ended published its node
  // before it ended, so a node seen incomplete after its job ended failed.
  const auto states = SlurmStates(ids);
  std::vector<NodeState> out;
  std::map<std::string, size_t> by_id;  // job id -> index in out
  for (const auto& j : sub.jobs) {
    NodeState s;
    s.job = j;
    const fs::path dir = workspace.root() / "cache" / (j.node + "-" + j.key16);
    if (SettledState(j, dir, &s)) {
      out.push_back(s);
      continue;
    }
    const std::vector<std::pair<std::string, std::string>> tasks = TasksOf(j);
    const auto records = j.shards > 1 ? ReadShardRecords(fs::path(dir.string() + ".partial"), j.shards)
                                      : std::vector<ShardRecord>{};
    std::set<int> recorded;
    for (const auto& r : records) recorded.insert(r.index);
    TaskCounts counts;
    for (const auto& [key, shard] : tasks) CountTask(j, key, shard, states, recorded, &counts, &s);
    bool input_failed = false;
    for (const auto& a : Split(j.after, ','))
      if (auto it = by_id.find(a); it != by_id.end())
        input_failed |= out[it->second].state == "failed" || out[it->second].state == "blocked";
    DecideState(j, dir, counts, static_cast<int>(tasks.size()), input_failed, &s);
    by_id[j.job_id] = out.size();
    out.push_back(s);
  }
  return out;
}

std::string FormatSlurmStatus(const std::vector<NodeState>& states) {
  bool variants = false;
  for (const auto& s : states) variants |= !s.job.variant.empty();
  std::vector<std::vector<std::string>> rows;
  rows.push_back({"node", "stage", "state", "job", "items", "wall_s", "cpu_s", "peak_mem",
                  "output", "shards"});
  if (variants) rows.back().insert(rows.back().begin(), "variant");
  for (const auto& s : states) {
    const Manifest& m = s.manifest;
    const bool has = s.has_manifest;
    std::string state = s.state + (s.detail.empty() ? "" : " (" + s.detail + ")");
    rows.push_back({s.job.node, s.job.stage, state,
                    s.job.job_id + (s.job.array.empty() ? "" : "_[" + s.job.array + "]"),
                    has && m.items ? std::to_string(m.items) : "-", has ? Seconds(m.seconds) : "-",
                    has && m.cpu_seconds > 0 ? Seconds(m.cpu_seconds) : "-",
                    has ? FormatBytes(m.peak_rss_bytes) : "-",
                    has ? FormatBytes(m.output_bytes) : "-", has ? std::to_string(m.shards) : "-"});
    if (variants) rows.back().insert(rows.back().begin(), s.job.variant);
  }
  return FormatColumns(rows, 6);
}

std::string CancelSlurmJobs(const std::vector<std::string>& ids) {
  if (ids.empty()) return "";
  std::vector<std::string> argv = {"scancel"};
  argv.insert(argv.end(), ids.begin(), ids.end());
  const ProcessResult r = RunProcess(argv, 60);
  if (r.ok()) return "";
  return r.error.empty() ? r.err : r.error + " " + r.err;
}

std::vector<NodeState> WaitForSlurm(const Workspace& workspace, const Submission& sub,
                                    double poll_seconds, const std::atomic<bool>* cancel,
                                    Reporter& reporter, bool* cancelled) {
  std::map<std::string, std::string> shown;  // line key -> last state shown
  *cancelled = false;
  while (true) {
    auto states = QuerySlurmStatus(workspace, sub);
    bool all_terminal = true;
    std::vector<std::string> active;
    for (const auto& s : states) {
      const std::string key = s.job.variant + "/" + s.job.node;
      const std::string text = s.state + (s.detail.empty() ? "" : " (" + s.detail + ")");
      if (shown[key] != text && s.job.job_id != "-") {
        reporter.Line((s.job.variant.empty() ? "" : s.job.variant + "/") + s.job.node + ": " +
                      text);
        shown[key] = text;
      }
      all_terminal &= s.terminal;
      active.insert(active.end(), s.active_ids.begin(), s.active_ids.end());
    }
    // Jobs that wait on a failed one will never run: end them.
    std::vector<std::string> never;
    for (const auto& s : states)
      if (s.state == "blocked") never.insert(never.end(), s.active_ids.begin(), s.active_ids.end());
    if (!never.empty()) CancelSlurmJobs(never);
    if (all_terminal) return states;
    if (cancel && cancel->load()) {
      *cancelled = true;
      // Array tasks are cancelled through their ids; pending arrays by their job id.
      std::set<std::string> jobs;
      for (const auto& id : active) jobs.insert(id.substr(0, id.find('_')));
      const std::string err = CancelSlurmJobs({jobs.begin(), jobs.end()});
      reporter.Line("interrupted: scancel " + Join({jobs.begin(), jobs.end()}, " ") +
                    (err.empty() ? "" : " failed: " + err));
      return QuerySlurmStatus(workspace, sub);
    }
    const auto until = std::chrono::steady_clock::now() +
                       std::chrono::milliseconds(static_cast<int>(poll_seconds * 1000));
    while (std::chrono::steady_clock::now() < until && !(cancel && cancel->load()))
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

}  // namespace locforge::host

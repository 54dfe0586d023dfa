// `locforge validate GRAPH` and `locforge run GRAPH --workspace DIR`.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <iostream>
#include <stdexcept>
#include <thread>

#include "cli.h"
#include "executor.h"
#include "graph.h"
#include "locforge/fs.h"
#include "locforge/params.h"
#include "slurm.h"
#include "run_record.h"

namespace locforge::host {

namespace {

struct GraphArgs {
  std::string graph;
  std::vector<Override> sets;
  std::vector<fs::path> plugin_paths;
  // run only
  std::string workspace;
  int threads = 0;
  bool force = false;
  int shard_index = 0, shard_count = 1;
  bool shard_from_array = false;  // --shard array/N: I from $SLURM_ARRAY_TASK_ID
  std::string variant;
  // Scheduler (--executor slurm) and its jobs (--node)
  std::string executor = "local";
  int shards = 4;
  bool shards_given = false;
  std::vector<SchedulerSetting> slurm_settings;
  bool wait = false;
  double poll_seconds = 10;
  std::string only_node, expect_key;
  std::vector<std::string> forward;  // what each job repeats: --set, --plugin-path
};

bool ParseShardNumbers(const std::string& text, int* index, int* count) {
  const size_t slash = text.find('/');
  int64_t i = 0, n = 0;
  if (slash == std::string::npos || !ParseInt(text.substr(0, slash), &i) ||
      !ParseInt(text.substr(slash + 1), &n) || n < 1 || i < 0 || i >= n || n > 100000)
    return false;
  *index = static_cast<int>(i);
  *count = static_cast<int>(n);
  return true;
}

// "I/N", or "array/N" in a Slurm array job (I = $SLURM_ARRAY_TASK_ID).
bool ParseShard(const std::string& text, int* index, int* count, bool* from_array) {
  *from_array = text.rfind("array/", 0) == 0;
  if (!*from_array) return ParseShardNumbers(text, index, count);
  const char* task = std::getenv("SLURM_ARRAY_TASK_ID");
  return task && *task && ParseShardNumbers(task + text.substr(5), index, count);
}

constexpr int kNotMine = -2;  // an option parser's "not one of mine"

std::string ShardUsage(bool from_array, const std::string& v) {
  return from_array ? "--shard array/N needs $SLURM_ARRAY_TASK_ID (a Slurm "
                      "array task) from 0 to N-1, got '" +
                          std::string(std::getenv("SLURM_ARRAY_TASK_ID") ? std::getenv("SLURM_ARRAY_TASK_ID") : "") +
                          "'"
                    : "--shard expects I/N with 0 <= I < N, got '" + v + "'";
}

// --set and --plugin-path (validate and run): -1 parsed, kNotMine, else the exit code.
int TakeGraphOption(const std::string& command, const Args& args, size_t* i, GraphArgs* out) {
  std::string v;
  if (TakeOption(args, i, "--set", &v)) {
    Override o;
    if (!ParseOverride(v, &o)) return UsageError(command, "--set expects KEY=VALUE, got '" + v + "'");
    out->sets.push_back(o);
    out->forward.insert(out->forward.end(), {"--set", v});
  } else if (TakeOption(args, i, "--plugin-path", &v)) {
    out->plugin_paths.push_back(fs::absolute(v));
    out->forward.insert(out->forward.end(), {"--plugin-path", fs::absolute(v).string()});
  } else {
    return kNotMine;
  }
  return -1;
}

// The options of a local run: -1 parsed, kNotMine, else the exit code.
int TakeLocalOption(const std::string& command, const Args& args, size_t* i, GraphArgs* out) {
  std::string v;
  if (TakeOption(args, i, "--workspace", &v)) {
    out->workspace = v;
  } else if (TakeOption(args, i, "--threads", &v)) {
    int64_t n = 0;
    if (!ParseInt(v, &n) || n < 1 || n > 4096)
      return UsageError(command, "--threads expects a number from 1 to 4096, got '" + v + "'");
    out->threads = static_cast<int>(n);
  } else if (TakeOption(args, i, "--shard", &v)) {
    if (!ParseShard(v, &out->shard_index, &out->shard_count, &out->shard_from_array))
      return UsageError(command, ShardUsage(out->shard_from_array, v));
  } else if (TakeOption(args, i, "--variant", &v)) {
    out->variant = v;
  } else if (args[*i] == "--force") {
    out->force = true;
  } else {
    return kNotMine;
  }
  return -1;
}

// The options of --executor slurm and of a job's run: -1 parsed, kNotMine, else the exit code.
int TakeSlurmOption(const std::string& command, const Args& args, size_t* i, GraphArgs* out) {
  std::string v;
  int64_t n = 0;
  if (TakeOption(args, i, "--executor", &v)) {
    if (v != "local" && v != "slurm") return UsageError(command, "--executor expects local or slurm, got '" + v + "'");
    out->executor = v;
  } else if (TakeOption(args, i, "--shards", &v)) {
    if (!ParseInt(v, &n) || n < 1 || n > 100000)
      return UsageError(command, "--shards expects a number from 1 to 100000, got '" + v + "'");
    out->shards = static_cast<int>(n);
    out->shards_given = true;
  } else if (TakeOption(args, i, "--slurm-opt", &v)) {
    SchedulerSetting setting;
    if (!ParseSchedulerSetting(v, &setting))
      return UsageError(command, "--slurm-opt expects [SELECTOR:]OPTION=VALUE, got '" + v + "'");
    out->slurm_settings.push_back(setting);
  } else if (args[*i] == "--wait") {
    out->wait = true;
  } else if (TakeOption(args, i, "--poll", &v)) {
    if (!ParseInt(v, &n) || n < 1 || n > 3600)
      return UsageError(command, "--poll expects seconds from 1 to 3600, got '" + v + "'");
    out->poll_seconds = static_cast<double>(n);
  } else if (TakeOption(args, i, "--node", &v)) {
    out->only_node = v;
  } else if (TakeOption(args, i, "--expect-key", &v)) {
    out->expect_key = v;
  } else {
    return kNotMine;
  }
  return -1;
}

// An unknown option (with the nearest known one), the graph, or an extra argument.
int TakeOther(const std::string& command, const Args& args, size_t i, bool run, GraphArgs* out) {
  if (args[i].rfind("-", 0) == 0) {
    std::vector<std::string> known = {"--set", "--plugin-path", "--help"};
    if (run)
      known.insert(known.end(), {"--workspace", "--threads", "--force", "--shard", "--variant", "--executor",
                                 "--shards", "--slurm-opt", "--wait", "--poll", "--node", "--expect-key"});
    const std::string hint = DidYouMean(args[i], known);
    return UsageError(command,
                      "unknown option '" + args[i] + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
  }
  if (!out->graph.empty()) return UsageError(command, "unexpected argument '" + args[i] + "'");
  out->graph = args[i];
  return -1;
}

// Options that need, or exclude, each other: -1 when fine, else the exit code.
int CheckCombinations(const std::string& command, bool run, const GraphArgs& a) {
  if (a.graph.empty()) return UsageError(command, "expected a graph file (GRAPH.yaml)");
  if (run && a.workspace.empty()) return UsageError(command, "--workspace DIR is required");
  if (a.force && a.shard_count > 1)
    return UsageError(command, "--force cannot be combined with --shard (shards share progress)");
  if (a.executor != "slurm") {
    for (const auto& [given, option] :
         {std::pair{a.shards_given, "--shards"}, {!a.slurm_settings.empty(), "--slurm-opt"}, {a.wait, "--wait"}})
      if (given) return UsageError(command, std::string(option) + " needs --executor slurm");
  } else {
    if (a.shard_count > 1 || !a.only_node.empty())
      return UsageError(command, "--executor slurm submits every node and shard itself: drop "
                                 "--shard and --node");
    if (a.force)
      return UsageError(command, "--force cannot be combined with --executor slurm (remove the "
                                 "nodes' folders from the workspace cache instead)");
    if (a.threads > 0)
      return UsageError(command, "with --executor slurm, threads follow each job's "
                                 "cpus-per-task: use --slurm-opt cpus-per-task=N");
  }
  if (!a.expect_key.empty() && a.only_node.empty()) return UsageError(command, "--expect-key needs --node");
  return -1;
}

// Parses the arguments of validate (run=false) or run. Returns -1 when fine,
// else the exit code after printing the usage error.
int ParseArgs(const std::string& command, const Args& args, bool run, GraphArgs* out) {
  try {
    for (size_t i = 0; i < args.size(); ++i) {
      int rc = TakeGraphOption(command, args, &i, out);
      if (rc == kNotMine && run) rc = TakeLocalOption(command, args, &i, out);
      if (rc == kNotMine && run) rc = TakeSlurmOption(command, args, &i, out);
      if (rc == kNotMine) rc = TakeOther(command, args, i, run, out);
      if (rc != -1) return rc;
    }
  } catch (const std::invalid_argument& e) {
    return UsageError(command, e.what());
  }
  return CheckCombinations(command, run, *out);
}

// Parses, loads plugins and validates every selected variant. Prints all
// problems; returns false when there were any.
bool PrepareGraph(const GraphArgs& args, runtime::Registry* registry,
                  std::vector<ResolvedGraph>* resolved, size_t* node_count,
                  std::vector<SchedulerSetting>* slurm = nullptr) {
  Graph graph;
  Diagnostics errors;
  auto print = [&errors] {
    for (const auto& d : Deduplicate(errors)) std::cerr << d.ToString() << "\n";
    return false;
  };
  // Parse problems do not stop validation: every problem is reported at once.
  if (!LoadGraph(args.graph, args.sets, &graph, &errors) && graph.variants.empty()) return print();
  std::vector<fs::path> extra = args.plugin_paths;
  for (const auto& [folder, where] : graph.plugin_paths) {
    std::error_code ec;
    if (!fs::is_directory(folder, ec))
      errors.push_back({where, "plugin folder '" + folder.string() + "' does not exist"});
    else
      extra.push_back(folder);
  }
  for (const auto& problem : LoadPlugins(registry, extra))
    errors.push_back(
        {{args.graph}, "plugin " + problem.file.string() + " refused: " + problem.message});
  for (const auto& d : registry->duplicates())
    errors.push_back({{args.graph}, "duplicate stage: " + d});
  std::vector<const GraphVariant*> selected;
  std::vector<std::string> names;
  for (const auto& v : graph.variants) {
    names.push_back(v.name);
    if (args.variant.empty() || v.name == args.variant) selected.push_back(&v);
  }
  if (selected.empty()) {
    const std::string hint = DidYouMean(args.variant, names);
    std::string all;
    for (const auto& n : names) all += (all.empty() ? "" : ", ") + (n.empty() ? "\"\"" : n);
    errors.push_back({{"--variant " + args.variant},
                      "unknown variant" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)") +
                          "; expected one of: " + all});
  }
  const StageLookup stages = LookupOf(*registry);
  *node_count = 0;
  for (const auto* v : selected) {
    ResolvedGraph r;
    if (ResolveVariant(*v, stages, &r, &errors)) {
      *node_count += r.nodes.size();
      resolved->push_back(std::move(r));
    }
  }
  // The `slurm:` section is checked by every command (a typo must not wait
  // for the first submission); --slurm-opt only where given.
  if (!resolved->empty()) {
    CheckSchedulerSettings(graph.slurm, *resolved, &errors);
    CheckSchedulerSettings(args.slurm_settings, *resolved, &errors);
  }
  if (slurm) *slurm = graph.slurm;
  if (!errors.empty()) return print();
  return true;
}

std::atomic<bool> g_cancel{false};

extern "C" void OnInterrupt(int signal) {
  g_cancel.store(true);
  std::signal(signal, SIG_DFL);  // a second Ctrl-C kills at once
}

// --executor slurm: submits, then (--wait) follows the jobs to the end.
int SubmitAndFollow(const GraphArgs& ga, const std::vector<ResolvedGraph>& resolved,
                    const std::vector<SchedulerSetting>& graph_slurm, const Workspace& workspace,
                    Reporter& reporter) {
  SlurmOptions so;
  so.shards = ga.shards;
  so.settings = ga.slurm_settings;
  so.graph = fs::absolute(ga.graph).lexically_normal();
  so.forward = ga.forward;
  std::error_code ec;
  so.locforge = fs::canonical("/proc/self/exe", ec);
  so.cwd = fs::current_path();
  Submission sub;
  try {
    sub = SubmitToSlurm(workspace, resolved, graph_slurm, so, reporter);
  } catch (const std::exception& e) {
    reporter.Line(std::string("error: ") + e.what());
    return 1;
  }
  size_t submitted = 0;
  for (const auto& j : sub.jobs) submitted += j.job_id != "-" && !j.log.empty();
  reporter.Line(std::to_string(submitted) + " jobs submitted, " +
                std::to_string(sub.jobs.size() - submitted) + " nodes cached; record: " +
                sub.file.string());
  if (!ga.wait) {
    std::cout << FormatSlurmStatus(QuerySlurmStatus(workspace, sub));
    std::cout << "follow with: locforge status " << workspace.root().string() << " --wait\n";
    return 0;
  }
  g_cancel.store(false);
  std::signal(SIGINT, OnInterrupt);
  std::signal(SIGTERM, OnInterrupt);
  bool cancelled = false;
  const auto states = WaitForSlurm(workspace, sub, ga.poll_seconds, &g_cancel, reporter, &cancelled);
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  const std::string table = FormatSlurmStatus(states);
  std::cout << table;
  reporter.FileOnly("\n" + table);
  bool ok = !cancelled;
  std::vector<std::string> failures;
  std::map<std::string, bool> complete;  // variant/node -> folder complete
  for (const auto& s : states) {
    const bool done = s.state == "done" || s.state == "cached";
    ok &= done;
    complete[s.job.variant + "/" + s.job.node] = done;
    if (done)  // nodes shared by variants: the job linked its own variant's
      workspace.Link(s.job.variant, s.job.node,
                     workspace.root() / "cache" / (s.job.node + "-" + s.job.key16));
    failures.insert(failures.end(), s.failures.begin(), s.failures.end());
  }
  std::vector<std::string> outputs;
  for (const auto& g : resolved)
    for (const auto& sink : g.sinks)
      if (complete[g.variant + "/" + sink]) outputs.push_back(workspace.LinkPath(g.variant, sink).string());
  if (!outputs.empty()) {
    std::cout << "outputs:\n";
    for (const auto& o : outputs) std::cout << "  " << o << "\n";
  }
  if (ok) return 0;
  for (const auto& f : failures) reporter.Line("error: " + f);
  if (cancelled)
    reporter.Line("error: interrupted; the jobs were cancelled. Finished nodes, shards and items "
                  "are kept: submit again to resume");
  else
    reporter.Line("error: the run did not finish (" + std::to_string(failures.size()) +
                  " failed jobs); fix the cause and submit again: only what is missing runs");
  return 1;
}

}  // namespace

int ValidateCommand(const Args& args) {
  if (WantsHelp(args)) {
    std::cout << HelpText("validate");
    return 0;
  }
  GraphArgs ga;
  if (const int rc = ParseArgs("validate", args, false, &ga); rc >= 0) return rc;
  runtime::Registry registry;
  std::vector<ResolvedGraph> resolved;
  size_t nodes = 0;
  if (!PrepareGraph(ga, &registry, &resolved, &nodes)) return 2;
  std::cout << ga.graph << ": ok, " << resolved.front().nodes.size() << " nodes";
  if (resolved.size() > 1 || !resolved.front().variant.empty())
    std::cout << ", " << resolved.size() << " variants";
  std::cout << "\n";
  return 0;
}

ExecOptions LocalOptions(const GraphArgs& ga) {
  ExecOptions options;
  options.only_node = ga.only_node;
  options.expect_key = ga.expect_key;
  options.threads = ga.threads > 0
                        ? ga.threads
                        : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  options.force = ga.force;
  options.shard_index = ga.shard_index;
  options.shard_count = ga.shard_count;
  options.cancel = &g_cancel;
  return options;
}

// Runs the graph here; Ctrl-C (or SIGTERM) stops it cleanly between items.
ExecResult RunHere(const std::vector<ResolvedGraph>& resolved, Workspace& workspace, Reporter& reporter,
                   const ExecOptions& options) {
  g_cancel.store(false);
  std::signal(SIGINT, OnInterrupt);
  std::signal(SIGTERM, OnInterrupt);
  Executor executor(workspace, reporter, options);
  ExecResult result;
  try {
    result = executor.Run(resolved);
  } catch (const std::exception& e) {
    result.failed = true;
    result.failure = e.what();
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  return result;
}

// The timing table, the outputs and the log's path.
void ReportRun(const ExecResult& result, bool matrix, const fs::path& log_file, Reporter& reporter) {
  const std::string table = FormatTable(result, matrix);
  std::cout << table;
  reporter.FileOnly("\n" + table);
  if (!result.outputs.empty()) {
    std::cout << "outputs:\n";
    for (const auto& o : result.outputs) std::cout << "  " << o << "\n";
  }
  std::cout << "log: " << log_file.string() << "\n";
}

// The exit code, with the failure or the sharded run's next step.
int Conclude(const ExecResult& result, const GraphArgs& ga, Reporter& reporter) {
  if (result.failed) {
    reporter.Line("error: " + result.failure);
    return 1;
  }
  if (result.waiting_for_shards) {
    reporter.Line("shard " + std::to_string(ga.shard_index) + "/" + std::to_string(ga.shard_count) +
                  " done; nodes downstream of sharded ones wait for the other shards. Run the "
                  "remaining shards, then the same command without --shard to finish.");
  }
  return 0;
}

int RunCommand(const Args& args) {
  if (WantsHelp(args)) {
    std::cout << HelpText("run");
    return 0;
  }
  GraphArgs ga;
  if (const int rc = ParseArgs("run", args, true, &ga); rc >= 0) return rc;
  runtime::Registry registry;
  std::vector<ResolvedGraph> resolved;
  size_t nodes = 0;
  std::vector<SchedulerSetting> graph_slurm;
  if (!PrepareGraph(ga, &registry, &resolved, &nodes, &graph_slurm)) return 2;
  runtime::SetComponentRegistry(&registry);

  std::unique_ptr<Workspace> workspace;
  try {
    workspace = std::make_unique<Workspace>(ga.workspace);
  } catch (const std::exception& e) {
    std::cerr << "locforge run: cannot use workspace '" << ga.workspace << "': " << e.what()
              << "\n";
    return 2;
  }
  Reporter reporter(std::cerr, ::isatty(STDERR_FILENO) != 0);
  const fs::path log_file = workspace->NewLogFile();
  reporter.OpenLogFile(log_file.string());
  std::string command_line = "locforge run";
  for (const auto& a : args) command_line += " " + a;
  reporter.FileOnly(command_line);
  for (const auto& p : registry.problems())
    reporter.FileOnly("warning: plugin " + p.file.string() + " refused and skipped: " + p.message);

  if (ga.executor == "slurm") return SubmitAndFollow(ga, resolved, graph_slurm, *workspace, reporter);

  const ExecOptions options = LocalOptions(ga);
  const std::string started = UtcNow();
  const auto start_time = std::chrono::steady_clock::now();
  const ExecResult result = RunHere(resolved, *workspace, reporter, options);
  ReportRun(result, resolved.size() > 1 || !resolved.front().variant.empty(), log_file, reporter);
  try {  // the record `locforge report` reads; a run does not fail for it
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
    WriteFileAtomic(RunRecordPath(log_file),
                    FormatRunRecord(MakeRunRecord(ga.graph, command_line, resolved, result, started, seconds,
                                                  options.threads)));
  } catch (const std::exception& e) {
    reporter.Line("warning: cannot write the run record: " + std::string(e.what()));
  }
  return Conclude(result, ga, reporter);
}

}  // namespace locforge::host

#include "executor.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <set>

#include "locforge/error.h"
#include "output_files.h"
#include "usage.h"

namespace locforge::host {

namespace {

std::string Label(const std::string& variant, const std::string& node) {
  return variant.empty() ? node : variant + "/" + node;
}

bool IsCancelled(const std::atomic<bool>* cancel) { return cancel && cancel->load(); }

// Items of a complete node, from its manifest (0 when not per-item, or when
// the manifest cannot be read: the count is informative only).
uint64_t ManifestItems(const fs::path& dir) {
  try {
    return ReadManifest(dir).items;
  } catch (const std::exception&) {
    return 0;
  }
}

NodeReport NewReport(const std::string& variant, const ResolvedNode& node) {
  NodeReport r;
  r.variant = variant;
  r.node = node.name;
  r.stage = node.stage->id;
  return r;
}

}  // namespace

ExecResult Executor::Run(const std::vector<ResolvedGraph>& variants) {
  ExecResult result;
  const bool only = !options_.only_node.empty();
  bool only_found = false;
  for (const auto& graph : variants) {
    std::map<std::string, std::string> keys;  // node -> cache key
    std::set<std::string> unavailable;        // nodes without a complete folder
    for (const auto& node : graph.nodes) {
      keys[node.name] = CacheKey(node, keys);
      if (only && (node.name != options_.only_node || only_found)) {
        // Another job's node: an input when complete, never computed here.
        const fs::path dir = workspace_.NodeDir(node.name, keys[node.name]);
        if (ServableFromCache(workspace_, Label(graph.variant, node.name), dir, reporter_)) {
          folders_[graph.variant + "/" + node.name] = dir;
          workspace_.Link(graph.variant, node.name, dir);
        } else {
          unavailable.insert(node.name);
        }
        continue;
      }
      NodeReport report = NewReport(graph.variant, node);
      if (only) {
        only_found = true;
        const std::string label = Label(graph.variant, node.name);
        std::string missing;
        for (const auto& in : node.inputs)
          if (unavailable.count(in.node) && missing.find("'" + in.node + "'") == std::string::npos)
            missing += (missing.empty() ? "'" : ", '") + in.node + "'";
        if (!options_.expect_key.empty() &&
            keys[node.name].compare(0, options_.expect_key.size(), options_.expect_key) != 0) {
          result.failed = true;
          result.failure = "node '" + label + "': its cache key is now " +
                           keys[node.name].substr(0, 16) + ", not the submitted " +
                           options_.expect_key +
                           " (parameters, input files or plugins changed since the submission); "
                           "submit again";
        } else if (!missing.empty()) {
          result.failed = true;
          result.failure = "node '" + label + "': input node " + missing +
                           " is not complete in " + workspace_.root().string() +
                           " (its job must finish first)";
        }
        if (result.failed) {
          report.status = "failed";
          result.nodes.push_back(report);
          continue;
        }
      }
      bool blocked = result.failed || IsCancelled(options_.cancel);
      for (const auto& in : node.inputs) blocked |= unavailable.count(in.node) > 0;
      if (blocked) {
        report.status = "skipped";
      } else {
        report = RunNode(graph, node, keys[node.name], &result);
      }
      if (report.folder.empty()) {
        unavailable.insert(node.name);
      } else {
        folders_[graph.variant + "/" + node.name] = report.folder;
        workspace_.Link(graph.variant, node.name, report.folder);
      }
      result.nodes.push_back(report);
    }
    for (const auto& sink : graph.sinks)
      if (!unavailable.count(sink) && !only)
        result.outputs.push_back(workspace_.LinkPath(graph.variant, sink).string());
  }
  if (only && !only_found && !result.failed) {
    result.failed = true;
    result.failure = "no node '" + options_.only_node + "' in the graph";
  }
  if (IsCancelled(options_.cancel) && !result.failed) {
    // Interrupted between nodes (or a stage that does not poll the flag).
    result.failed = true;
    result.failure = "interrupted; finished nodes and items are kept, run again to resume";
  }
  return result;
}

NodeReport Executor::RunNode(const ResolvedGraph& graph, const ResolvedNode& node,
                             const std::string& key, ExecResult* result) {
  NodeReport report = NewReport(graph.variant, node);
  const std::string label = Label(graph.variant, node.name);
  if (auto known = by_key_.find(key); known != by_key_.end()) {
    // The same node (same key) in an earlier variant of this run.
    report.status = known->second.folder.empty() ? "skipped" : "cached";
    report.folder = known->second.folder.string();
    if (!report.folder.empty()) report.items = ManifestItems(report.folder);
    return report;
  }
  const fs::path dir = workspace_.NodeDir(node.name, key);
  Done done;
  if (!options_.force && ServableFromCache(workspace_, label, dir, reporter_)) {
    done = {"cached", dir};
    report.items = ManifestItems(dir);
    report.output_bytes = OutputBytes(dir);
    reporter_.FileOnly(label + ": cached in " + dir.string());
  } else {
    done = Compute(label, graph, node, key, dir, &report, result);
  }
  by_key_[key] = done;
  report.status = done.status;
  report.folder = done.folder.string();
  return report;
}

std::vector<runtime::InputArtifact> Executor::Inputs(const ResolvedGraph& graph,
                                                     const ResolvedNode& node) {
  std::vector<runtime::InputArtifact> out;
  for (const auto& in : node.inputs)
    out.push_back({in.port, in.artifact_type, folders_.at(graph.variant + "/" + in.node)});
  return out;
}

namespace {

// This shard's items are done (and, for the last one, finalized): its
// record tells a re-submission to skip it and the manifest its cost.
void RecordShard(const fs::path& partial, int index, int count, const runtime::RunResult& r,
                 const NodeReport& report, const std::string& started) {
  ShardRecord record;
  record.index = index;
  record.count = count;
  record.items = r.items_total;
  record.seconds = report.seconds;
  record.cpu_seconds = report.cpu_seconds;
  record.peak_rss_bytes = report.peak_rss_bytes;
  char host[256] = {};
  ::gethostname(host, sizeof(host) - 1);
  record.host = host;
  record.started = started;
  record.finished = UtcNow();
  WriteShardRecord(partial, record);
}

// The cost of a finished run; of a sharded one, the sum of the shards'
// records (one that finished at the same moment as this one may not have
// written its record yet: then it is not counted).
host::Manifest RunCost(const runtime::RunResult& r, const NodeReport& report, const std::string& started,
                       const fs::path& partial, bool sharded, int shard_count) {
  host::Manifest m;
  m.items = r.items_total;
  m.seconds = report.seconds;
  m.cpu_seconds = report.cpu_seconds;
  m.peak_rss_bytes = report.peak_rss_bytes;
  m.started = started;
  if (!sharded) return m;
  const auto records = ReadShardRecords(partial, shard_count);
  if (records.empty()) return m;
  m = {};
  m.shards = static_cast<int>(records.size());
  m.started = started;
  for (const auto& rec : records) {
    m.items += rec.items;
    m.seconds += rec.seconds;
    m.cpu_seconds += rec.cpu_seconds;
    m.peak_rss_bytes = std::max(m.peak_rss_bytes, rec.peak_rss_bytes);
    m.started = std::min(m.started, rec.started);
  }
  return m;
}

}  // namespace

// Locks the node's folder (shards of one node run side by side; an unsharded
// run waits for them) and prepares its partial folder: a Done when there is
// nothing to run (complete meanwhile) or the folder cannot be prepared.
std::optional<Executor::Done> Executor::LockNode(const std::string& label, const ResolvedNode& node,
                                                 const fs::path& dir, std::optional<FileLock>* node_lock,
                                                 std::optional<FileLock>* shard_lock, fs::path* partial,
                                                 ExecResult* result) {
  const bool per_item = node.stage->per_item();
  try {
    if (per_item && options_.shard_count > 1) {
      node_lock->emplace(workspace_.LockFile(dir, ".lock"), FileLock::kShared);
      shard_lock->emplace(workspace_.LockFile(dir, ".shard-" + std::to_string(options_.shard_index) + "-of-" +
                                                       std::to_string(options_.shard_count) + ".lock"),
                          FileLock::kExclusive);
    } else {
      node_lock->emplace(workspace_.LockFile(dir, ".lock"), FileLock::kExclusive);
    }
    if (!options_.force && Workspace::IsComplete(dir)) return Done{"cached", dir};  // done meanwhile
    *partial = Workspace::PartialDir(dir, per_item);
    if (per_item) {
      if (options_.force) fs::remove_all(*partial);  // journals of an earlier run
    } else {
      Workspace::RemoveStalePartials(dir);
    }
  } catch (const std::exception& e) {
    result->failed = true;
    result->failure = "node '" + label + "' (" + node.stage->id + "): " + e.what();
    return Done{"failed", {}};
  }
  return std::nullopt;
}

runtime::RunOptions Executor::RunOptionsFor(const std::string& label, bool per_item, const fs::path& partial,
                                            const std::vector<runtime::InputArtifact>& inputs) {
  runtime::RunOptions run;
  run.workspace = workspace_.root();
  run.output_dir = partial;
  run.inputs = inputs;
  run.threads = options_.threads;
  run.shard_index = per_item ? options_.shard_index : 0;
  run.shard_count = per_item ? options_.shard_count : 1;
  run.cancel = options_.cancel;
  run.log = [this, label](int level, const std::string& m) { reporter_.Log(label, level, m); };
  run.progress = [this, label](uint64_t done, uint64_t total, const std::string& what) {
    reporter_.Progress(label, done, total, what);
  };
  return run;
}

Executor::Done Executor::Compute(const std::string& label, const ResolvedGraph& graph,
                                 const ResolvedNode& node, const std::string& key,
                                 const fs::path& dir, NodeReport* report, ExecResult* result) {
  const bool per_item = node.stage->per_item();
  std::optional<FileLock> node_lock, shard_lock;
  fs::path partial;
  const auto inputs = Inputs(graph, node);
  if (const std::optional<Done> d = LockNode(label, node, dir, &node_lock, &shard_lock, &partial, result)) return *d;
  const runtime::RunOptions run = RunOptionsFor(label, per_item, partial, inputs);

  reporter_.NodeStarted(label, node.stage->id);
  const auto start = std::chrono::steady_clock::now();
  const std::string started = UtcNow();
  const UsageMeter meter;
  auto measure = [&] {
    report->seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const Usage used = meter.Stop();
    report->cpu_seconds = used.cpu_seconds;
    report->peak_rss_bytes = used.peak_rss_bytes;
  };
  try {
    runtime::StageInstance instance(*node.stage, node.params);
    const runtime::RunResult r = instance.Run(run);
    report->items = r.items_total;
    measure();
    return FinishRun(label, node, key, dir, partial, inputs, r, started, report, result);
  } catch (const std::exception& e) {
    measure();
    return Failed(label, node, dir, partial, e.what(), *report, result);
  }
}

// After the stage's run: this shard's record, or the node published with its
// manifest (the shards' cost summed).
Executor::Done Executor::FinishRun(const std::string& label, const ResolvedNode& node, const std::string& key,
                                   const fs::path& dir, const fs::path& partial,
                                   const std::vector<runtime::InputArtifact>& inputs, const runtime::RunResult& r,
                                   const std::string& started, NodeReport* report, ExecResult* result) {
  const bool sharded = node.stage->per_item() && options_.shard_count > 1;
  std::optional<FileLock> publish;
  if (sharded) {
    publish.emplace(workspace_.LockFile(dir, ".publish.lock"), FileLock::kExclusive);
    if (Workspace::IsComplete(dir)) {
      reporter_.NodeFinished(label, "ran (published by another shard)", r.items_total, report->seconds);
      return {"ran", dir};
    }
    RecordShard(partial, options_.shard_index, options_.shard_count, r, *report, started);
  }
  if (!r.complete) {
    result->waiting_for_shards = true;
    reporter_.NodeFinished(label,
                           "shard " + std::to_string(options_.shard_index) + "/" +
                               std::to_string(options_.shard_count) + " done",
                           r.items_total, report->seconds);
    return {"partial", {}};
  }
  host::Manifest m = RunCost(r, *report, started, partial, sharded, options_.shard_count);
  m.output_bytes = OutputBytes(partial);
  report->output_bytes = m.output_bytes;
  RecordOutputFiles(partial, &m);
  Publish(partial, dir, Manifest(node, key, inputs, m));
  const std::string status = r.items_resumed > 0 ? "resumed" : "ran";
  reporter_.NodeFinished(label, status, r.items_total, report->seconds);
  return {status, dir};
}

// A failed or interrupted run. Shards running side by side may both see every
// item done and both finalize; the first to publish wins and the other one's
// result (or its error from the folder moving away) is moot.
Executor::Done Executor::Failed(const std::string& label, const ResolvedNode& node, const fs::path& dir,
                                const fs::path& partial, const std::string& what, const NodeReport& report,
                                ExecResult* result) {
  const bool per_item = node.stage->per_item();
  if (per_item && options_.shard_count > 1) {
    FileLock publish(workspace_.LockFile(dir, ".publish.lock"), FileLock::kExclusive);
    if (Workspace::IsComplete(dir)) {
      reporter_.NodeFinished(label, "ran (published by another shard)", report.items, report.seconds);
      return {"ran", dir};
    }
  }
  const bool interrupted = IsCancelled(options_.cancel);
  std::error_code ec;
  if (!per_item) fs::remove_all(partial, ec);  // nothing to resume in a whole-stage run
  result->failed = true;
  result->failure = "node '" + label + "' (" + node.stage->id + ") " +
                    (interrupted ? "interrupted" : std::string("failed: ") + what) +
                    (per_item ? "; finished items are kept, run again to resume" : "");
  reporter_.NodeFinished(label, interrupted ? "interrupted" : "failed", report.items, report.seconds);
  return {"failed", {}};
}

std::string Executor::Manifest(const ResolvedNode& node, const std::string& key,
                               const std::vector<runtime::InputArtifact>& inputs,
                               host::Manifest m) const {
  const LfPluginInfo* plugin = node.stage->plugin->info;
  m.stage = node.stage->id;
  m.plugin = plugin->name ? plugin->name : "";
  m.plugin_version = plugin->version ? plugin->version : "";
  m.stage_version = node.stage->version;
  m.plugin_file = node.stage->plugin->file.string();
  m.key = key;
  m.params = node.params;
  for (const auto& in : inputs) m.inputs.push_back({in.port, in.artifact_type, in.path.string()});
  m.finished = UtcNow();
  return FormatManifest(m);
}

std::string FormatBytes(uint64_t bytes) {
  if (bytes == 0) return "-";
  const char* units[] = {"B", "kB", "MB", "GB", "TB"};
  double v = static_cast<double>(bytes);
  int u = 0;
  while (v >= 1000 && u < 4) {
    v /= 1000;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof(buf), u == 0 || v >= 100 ? "%.0f %s" : "%.1f %s", v, units[u]);
  return buf;
}

std::string FormatColumns(const std::vector<std::vector<std::string>>& rows, size_t numeric) {
  std::vector<size_t> width;
  for (const auto& row : rows) {
    width.resize(std::max(width.size(), row.size()), 0);
    for (size_t c = 0; c < row.size(); ++c) width[c] = std::max(width[c], row[c].size());
  }
  std::string out;
  for (const auto& row : rows) {
    std::string line;
    for (size_t c = 0; c < row.size(); ++c) {
      const bool right = c + numeric >= row.size();
      const std::string pad(width[c] - row[c].size(), ' ');
      line += (c ? "  " : "") + (right ? pad + row[c] : row[c] + (c + 1 < row.size() ? pad : ""));
    }
    out += line + "\n";
  }
  return out;
}

std::string FormatTable(const ExecResult& result, bool with_variants) {
  std::vector<std::vector<std::string>> rows;
  rows.push_back({"node", "stage", "status", "items", "seconds", "cpu_s", "peak_mem", "output"});
  if (with_variants) rows.back().insert(rows.back().begin(), "variant");
  for (const auto& n : result.nodes) {
    char secs[32], cpu[32];
    std::snprintf(secs, sizeof(secs), "%.2f", n.seconds);
    std::snprintf(cpu, sizeof(cpu), "%.2f", n.cpu_seconds);
    const bool ran = n.peak_rss_bytes > 0;
    rows.push_back({n.node, n.stage, n.status, n.items ? std::to_string(n.items) : "-", secs,
                    ran ? cpu : "-", ran ? FormatBytes(n.peak_rss_bytes) : "-",
                    FormatBytes(n.output_bytes)});
    if (with_variants) rows.back().insert(rows.back().begin(), n.variant);
  }
  return FormatColumns(rows, 5);
}

}  // namespace locforge::host

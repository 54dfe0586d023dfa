#include "executor.h"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <set>

#include "locforge/error.h"

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
  for (const auto& graph : variants) {
    std::map<std::string, std::string> keys;  // node -> cache key
    std::set<std::string> unavailable;        // nodes without a complete folder
    for (const auto& node : graph.nodes) {
      keys[node.name] = CacheKey(node, keys);
      bool blocked = result.failed || IsCancelled(options_.cancel);
      for (const auto& in : node.inputs) blocked |= unavailable.count(in.node) > 0;
      NodeReport report = NewReport(graph.variant, node);
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
      if (!unavailable.count(sink))
        result.outputs.push_back(workspace_.LinkPath(graph.variant, sink).string());
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
  if (!options_.force && Workspace::IsComplete(dir)) {
    done = {"cached", dir};
    report.items = ManifestItems(dir);
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

Executor::Done Executor::Compute(const std::string& label, const ResolvedGraph& graph,
                                 const ResolvedNode& node, const std::string& key,
                                 const fs::path& dir, NodeReport* report, ExecResult* result) {
  const bool per_item = node.stage->per_item();
  std::optional<FileLock> node_lock, shard_lock;
  fs::path partial;
  const auto inputs = Inputs(graph, node);
  try {
    if (per_item && options_.shard_count > 1) {
      // Shards of one node run side by side; an unsharded run waits for them.
      node_lock.emplace(workspace_.LockFile(dir, ".lock"), FileLock::kShared);
      shard_lock.emplace(workspace_.LockFile(dir, ".shard-" + std::to_string(options_.shard_index) +
                                                      "-of-" + std::to_string(options_.shard_count) +
                                                      ".lock"),
                         FileLock::kExclusive);
    } else {
      node_lock.emplace(workspace_.LockFile(dir, ".lock"), FileLock::kExclusive);
    }
    if (!options_.force && Workspace::IsComplete(dir)) return {"cached", dir};  // done meanwhile
    partial = Workspace::PartialDir(dir, per_item);
    if (per_item) {
      if (options_.force) fs::remove_all(partial);  // journals of an earlier run
    } else {
      Workspace::RemoveStalePartials(dir);
    }
  } catch (const std::exception& e) {
    result->failed = true;
    result->failure = "node '" + label + "' (" + node.stage->id + "): " + e.what();
    return {"failed", {}};
  }

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

  reporter_.NodeStarted(label, node.stage->id);
  const auto start = std::chrono::steady_clock::now();
  const bool sharded = per_item && options_.shard_count > 1;
  // Shards running side by side may both see every item done and both
  // finalize; the first to publish wins and the other one's result (or its
  // error from the folder moving away) is moot.
  auto published_by_another_shard = [&] {
    if (!sharded) return false;
    FileLock publish(workspace_.LockFile(dir, ".publish.lock"), FileLock::kExclusive);
    return Workspace::IsComplete(dir);
  };
  std::string status;
  try {
    runtime::StageInstance instance(*node.stage, node.params);
    const runtime::RunResult r = instance.Run(run);
    report->items = r.items_total;
    report->seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::optional<FileLock> publish;
    if (sharded) {
      publish.emplace(workspace_.LockFile(dir, ".publish.lock"), FileLock::kExclusive);
      if (Workspace::IsComplete(dir)) {
        reporter_.NodeFinished(label, "ran (published by another shard)", r.items_total,
                               report->seconds);
        return {"ran", dir};
      }
    }
    if (!r.complete) {
      result->waiting_for_shards = true;
      reporter_.NodeFinished(label,
                             "shard " + std::to_string(options_.shard_index) + "/" +
                                 std::to_string(options_.shard_count) + " done",
                             r.items_total, report->seconds);
      return {"partial", {}};
    }
    Publish(partial, dir, Manifest(node, key, inputs, r.items_total, report->seconds));
    status = r.items_resumed > 0 ? "resumed" : "ran";
    reporter_.NodeFinished(label, status, r.items_total, report->seconds);
    return {status, dir};
  } catch (const std::exception& e) {
    report->seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (published_by_another_shard()) {
      reporter_.NodeFinished(label, "ran (published by another shard)", report->items,
                             report->seconds);
      return {"ran", dir};
    }
    const bool interrupted = IsCancelled(options_.cancel);
    std::error_code ec;
    if (!per_item) fs::remove_all(partial, ec);  // nothing to resume in a whole-stage run
    result->failed = true;
    result->failure = "node '" + label + "' (" + node.stage->id + ") " +
                      (interrupted ? "interrupted" : std::string("failed: ") + e.what()) +
                      (per_item ? "; finished items are kept, run again to resume" : "");
    reporter_.NodeFinished(label, interrupted ? "interrupted" : "failed", report->items,
                           report->seconds);
    return {"failed", {}};
  }
}

std::string Executor::Manifest(const ResolvedNode& node, const std::string& key,
                               const std::vector<runtime::InputArtifact>& inputs, uint64_t items,
                               double seconds) const {
  const LfPluginInfo* plugin = node.stage->plugin->info;
  host::Manifest m;
  m.stage = node.stage->id;
  m.plugin = plugin->name ? plugin->name : "";
  m.plugin_version = plugin->version ? plugin->version : "";
  m.stage_version = node.stage->version;
  m.plugin_file = node.stage->plugin->file.string();
  m.key = key;
  m.params = node.params;
  for (const auto& in : inputs) m.inputs.push_back({in.port, in.artifact_type, in.path.string()});
  m.finished = UtcNow();
  m.items = items;
  m.seconds = seconds;
  return FormatManifest(m);
}

std::string FormatTable(const ExecResult& result, bool with_variants) {
  std::vector<std::vector<std::string>> rows;
  rows.push_back({"node", "stage", "status", "items", "seconds"});
  if (with_variants) rows.back().insert(rows.back().begin(), "variant");
  for (const auto& n : result.nodes) {
    char secs[32];
    std::snprintf(secs, sizeof(secs), "%.2f", n.seconds);
    rows.push_back({n.node, n.stage, n.status, n.items ? std::to_string(n.items) : "-", secs});
    if (with_variants) rows.back().insert(rows.back().begin(), n.variant);
  }
  std::vector<size_t> width(rows.front().size(), 0);
  for (const auto& row : rows)
    for (size_t c = 0; c < row.size(); ++c) width[c] = std::max(width[c], row[c].size());
  std::string out;
  for (const auto& row : rows) {
    std::string line;
    for (size_t c = 0; c < row.size(); ++c) {
      const bool numeric = c + 2 >= row.size();
      const std::string pad(width[c] - row[c].size(), ' ');
      line += (c ? "  " : "") + (numeric ? pad + row[c] : row[c] + (c + 1 < row.size() ? pad : ""));
    }
    out += line + "\n";
  }
  return out;
}

}  // namespace locforge::host

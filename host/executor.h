// Runs resolved graph variants in a workspace: topological, cached by key
// (a node whose folder is complete is not rerun), resumable per-item nodes,
// sharded per-item nodes, and matrix variants sharing identical nodes.
#ifndef LOCFORGE_HOST_EXECUTOR_H_
#define LOCFORGE_HOST_EXECUTOR_H_

#include <atomic>
#include <optional>
#include <string>
#include <vector>

#include "graph.h"
#include "progress.h"
#include "workspace.h"

namespace locforge::host {

struct ExecOptions {
  int threads = 1;
  bool force = false;  // rerun every node even when its folder is complete
  int shard_index = 0;
  int shard_count = 1;
  const std::atomic<bool>* cancel = nullptr;
  // Run this node only (a scheduler's job): the other nodes are its inputs,
  // used when complete; a missing input fails the run.
  std::string only_node;
  // With only_node: the first 16 hex of the key the submitter computed; a
  // different key (inputs or parameters changed since) fails the run.
  std::string expect_key;
};

struct NodeReport {
  std::string variant;
  std::string node;
  std::string stage;
  std::string status;  // ran, cached, resumed, partial (shard done), failed, skipped
  uint64_t items = 0;
  double seconds = 0;
  double cpu_seconds = 0;       // this run's (host/usage.h)
  uint64_t peak_rss_bytes = 0;
  uint64_t output_bytes = 0;    // when complete
  std::string folder;  // the node's artifact folder when complete
};

struct ExecResult {
  std::vector<NodeReport> nodes;
  bool failed = false;
  std::string failure;               // one line naming the node and the plugin's message
  bool waiting_for_shards = false;   // this shard is done; other shards still pending
  std::vector<std::string> outputs;  // workspace links of the final outputs
};

class Executor {
 public:
  Executor(Workspace& workspace, Reporter& reporter, ExecOptions options)
      : workspace_(workspace), reporter_(reporter), options_(options) {}

  ExecResult Run(const std::vector<ResolvedGraph>& variants);

 private:
  struct Done {
    std::string status;
    fs::path folder;  // empty when not complete
  };
  NodeReport RunNode(const ResolvedGraph& graph, const ResolvedNode& node, const std::string& key,
                     ExecResult* result);
  Done Compute(const std::string& label, const ResolvedGraph& graph, const ResolvedNode& node,
               const std::string& key, const fs::path& dir, NodeReport* report, ExecResult* result);
  // The steps of Compute.
  std::optional<Done> LockNode(const std::string& label, const ResolvedNode& node, const fs::path& dir,
                               std::optional<FileLock>* node_lock, std::optional<FileLock>* shard_lock,
                               fs::path* partial, ExecResult* result);
  runtime::RunOptions RunOptionsFor(const std::string& label, bool per_item, const fs::path& partial,
                                    const std::vector<runtime::InputArtifact>& inputs);
  Done FinishRun(const std::string& label, const ResolvedNode& node, const std::string& key, const fs::path& dir,
                 const fs::path& partial, const std::vector<runtime::InputArtifact>& inputs,
                 const runtime::RunResult& r, const std::string& started, NodeReport* report, ExecResult* result);
  Done Failed(const std::string& label, const ResolvedNode& node, const fs::path& dir, const fs::path& partial,
              const std::string& what, const NodeReport& report, ExecResult* result);
  std::vector<runtime::InputArtifact> Inputs(const ResolvedGraph& graph, const ResolvedNode& node);
  std::string Manifest(const ResolvedNode& node, const std::string& key,
                       const std::vector<runtime::InputArtifact>& inputs, host::Manifest m) const;

  Workspace& workspace_;
  Reporter& reporter_;
  ExecOptions options_;
  std::map<std::string, Done> by_key_;  // nodes already handled in this run (shared by variants)
  std::map<std::string, fs::path> folders_;  // "variant/node" -> complete folder
};

// The timing table printed at the end of a run.
std::string FormatTable(const ExecResult& result, bool with_variants);
// Rows (first = header) as aligned columns; the last `numeric` columns right-aligned.
std::string FormatColumns(const std::vector<std::vector<std::string>>& rows, size_t numeric);
// "1.2 GB", "340 MB", "12 kB", "-" for 0.
std::string FormatBytes(uint64_t bytes);

}  // namespace locforge::host

#endif  // LOCFORGE_HOST_EXECUTOR_H_

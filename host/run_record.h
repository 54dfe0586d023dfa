// The record of one `locforge run`, written beside its log as
// logs/run-<UTC time>.json: the graph, the command, and every node with its
// stage, version, parameters, inputs, status (ran or cached), items and time.
// `locforge report` reads the newest one.
#ifndef LOCFORGE_HOST_RUN_RECORD_H_
#define LOCFORGE_HOST_RUN_RECORD_H_

#include <string>
#include <vector>

#include "executor.h"
#include "graph.h"

namespace locforge::host {

struct RunRecord {
  struct Input {
    std::string port, node, out_port;
  };
  struct Node {
    std::string variant, name, stage, version, status;
    uint64_t items = 0;
    double seconds = 0;
    std::string folder;  // absolute; empty when the node did not complete
    std::vector<std::pair<std::string, std::string>> params;  // display form: lists joined by ", "
    std::vector<Input> inputs;
  };
  std::string locforge_version;
  std::string graph;  // absolute graph file
  std::string description;
  std::string command;
  std::string started, finished;  // UTC
  double seconds = 0;             // wall-clock of the whole run
  int threads = 0;
  bool failed = false;
  std::string failure;
  std::vector<Node> nodes;
};

// The record file of a run log: logs/run-X.log -> logs/run-X.json.
fs::path RunRecordPath(const fs::path& log_file);
// Builds the record of a finished run.
RunRecord MakeRunRecord(const std::string& graph_file, const std::string& command,
                        const std::vector<ResolvedGraph>& graphs, const ExecResult& result,
                        const std::string& started, double seconds, int threads);
std::string FormatRunRecord(const RunRecord& record);  // JSON
// Throws InputError naming the file and field when it is not such a record.
RunRecord ReadRunRecord(const fs::path& file);
// The newest logs/run-*.json of a workspace; empty when there is none.
fs::path NewestRunRecord(const fs::path& workspace);
// The newest WORKSPACE/logs/run-*<extension> (".log", ".json") by start order.
fs::path NewestRun(const fs::path& workspace, const std::string& extension);
// A parameter's canonical value as a person reads it: list elements joined
// by ", ", a component as "kind/name {a=1, b=2}".
std::string DisplayValue(const std::string& canonical);

}  // namespace locforge::host

#endif  // LOCFORGE_HOST_RUN_RECORD_H_

#include "run_record.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>

#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/version.h"
#include "workspace.h"

namespace locforge::host {

fs::path RunRecordPath(const fs::path& log_file) {
  fs::path p = log_file;
  p.replace_extension(".json");
  return p;
}

std::string DisplayValue(const std::string& canonical) {
  std::string out;
  for (char c : canonical) {
    if (c == LF_LIST_SEPARATOR)
      out += ", ";
    else if (c == LF_COMPONENT_SEPARATOR)
      out += out.find('{') == std::string::npos ? " {" : ", ";
    else
      out += c;
  }
  if (out.find('{') != std::string::npos) out += "}";
  return out;
}

RunRecord MakeRunRecord(const std::string& graph_file, const std::string& command,
                        const std::vector<ResolvedGraph>& graphs, const ExecResult& result,
                        const std::string& started, double seconds, int threads) {
  RunRecord r;
  r.locforge_version = LOCFORGE_VERSION_STRING;
  r.graph = fs::absolute(graph_file).lexically_normal().string();
  try {
    const YAML::Node root = YAML::LoadFile(graph_file);
    if (root.IsMap() && root["description"] && root["description"].IsScalar())
      r.description = root["description"].Scalar();
  } catch (const std::exception&) {
    // The graph was parsed before the run; a description is informative only.
  }
  r.command = command;
  r.started = started;
  r.finished = UtcNow();
  r.seconds = seconds;
  r.threads = threads;
  r.failed = result.failed;
  r.failure = result.failure;
  for (const auto& report : result.nodes) {
    RunRecord::Node n;
    n.variant = report.variant;
    n.name = report.node;
    n.stage = report.stage;
    n.status = report.status;
    n.items = report.items;
    n.seconds = report.seconds;
    if (!report.folder.empty()) n.folder = fs::absolute(report.folder).lexically_normal().string();
    for (const auto& g : graphs) {
      if (g.variant != report.variant) continue;
      for (const auto& node : g.nodes) {
        if (node.name != report.node) continue;
        n.version = node.stage->version;
        for (const auto& [name, value] : node.params) n.params.emplace_back(name, DisplayValue(value));
        for (const auto& in : node.inputs) n.inputs.push_back({in.port, in.node, in.out_port});
      }
    }
    r.nodes.push_back(std::move(n));
  }
  return r;
}

std::string FormatRunRecord(const RunRecord& r) {
  char secs[32];
  std::snprintf(secs, sizeof(secs), "%.3f", r.seconds);
  std::string j = "{\n";
  j += "  \"locforge\": " + JsonString(r.locforge_version) + ",\n";
  j += "  \"graph\": " + JsonString(r.graph) + ",\n";
  j += "  \"description\": " + JsonString(r.description) + ",\n";
  j += "  \"command\": " + JsonString(r.command) + ",\n";
  j += "  \"started\": " + JsonString(r.started) + ",\n";
  j += "  \"finished\": " + JsonString(r.finished) + ",\n";
  j += "  \"seconds\": " + std::string(secs) + ",\n";
  j += "  \"threads\": " + std::to_string(r.threads) + ",\n";
  j += "  \"failed\": " + std::string(r.failed ? "true" : "false") + ",\n";
  j += "  \"failure\": " + JsonString(r.failure) + ",\n";
  j += "  \"nodes\": [";
  for (size_t i = 0; i < r.nodes.size(); ++i) {
    const auto& n = r.nodes[i];
    std::snprintf(secs, sizeof(secs), "%.3f", n.seconds);
    j += std::string(i ? "," : "") + "\n    {\"variant\": " + JsonString(n.variant) + ", \"name\": " +
         JsonString(n.name) + ", \"stage\": " + JsonString(n.stage) + ", \"version\": " + JsonString(n.version) +
         ", \"status\": " + JsonString(n.status) + ", \"items\": " + std::to_string(n.items) +
         ", \"seconds\": " + secs + ", \"folder\": " + JsonString(n.folder) + ",\n     \"params\": {";
    for (size_t p = 0; p < n.params.size(); ++p)
      j += std::string(p ? ", " : "") + JsonString(n.params[p].first) + ": " + JsonString(n.params[p].second);
    j += "},\n     \"inputs\": [";
    for (size_t p = 0; p < n.inputs.size(); ++p)
      j += std::string(p ? ", " : "") + "{\"port\": " + JsonString(n.inputs[p].port) + ", \"node\": " +
           JsonString(n.inputs[p].node) + ", \"out_port\": " + JsonString(n.inputs[p].out_port) + "}";
    j += "]}";
  }
  j += "\n  ]\n}\n";
  return j;
}

RunRecord ReadRunRecord(const fs::path& file) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw InputError(file.string(), e.mark.line + 1, "", "not JSON: " + e.msg);
  }
  if (!root.IsMap() || !root["nodes"] || !root["nodes"].IsSequence())
    throw InputError(file.string(), 1, "nodes", "expected a run record (a JSON object with a nodes list)");
  auto text = [](const YAML::Node& n, const char* key) {
    return n[key] && n[key].IsScalar() ? n[key].Scalar() : std::string();
  };
  RunRecord r;
  try {
    r.locforge_version = text(root, "locforge");
    r.graph = text(root, "graph");
    r.description = text(root, "description");
    r.command = text(root, "command");
    r.started = text(root, "started");
    r.finished = text(root, "finished");
    if (root["seconds"]) r.seconds = root["seconds"].as<double>();
    if (root["threads"]) r.threads = root["threads"].as<int>();
    if (root["failed"]) r.failed = root["failed"].as<bool>();
    r.failure = text(root, "failure");
    for (const auto& n : root["nodes"]) {
      RunRecord::Node node;
      node.variant = text(n, "variant");
      node.name = text(n, "name");
      node.stage = text(n, "stage");
      node.version = text(n, "version");
      node.status = text(n, "status");
      if (n["items"]) node.items = n["items"].as<uint64_t>();
      if (n["seconds"]) node.seconds = n["seconds"].as<double>();
      node.folder = text(n, "folder");
      if (n["params"] && n["params"].IsMap())
        for (const auto& p : n["params"]) node.params.emplace_back(p.first.Scalar(), p.second.Scalar());
      if (n["inputs"] && n["inputs"].IsSequence())
        for (const auto& in : n["inputs"]) node.inputs.push_back({text(in, "port"), text(in, "node"), text(in, "out_port")});
      r.nodes.push_back(std::move(node));
    }
  } catch (const YAML::Exception& e) {
    throw InputError(file.string(), e.mark.line + 1, "", "malformed run record: " + e.msg);
  }
  return r;
}

// "run-<stamp>[-<n>].<ext>" in the order the runs started: runs within one
// second get "-1", "-2", ... after the first, which a plain string order
// would put before it ('-' < '.').
std::pair<std::string, int> RunOrder(const fs::path& file) {
  const std::string stem = file.stem().string();
  const size_t dash = stem.find('-', 4);
  if (dash == std::string::npos) return {stem, 0};
  try {
    return {stem.substr(0, dash), std::stoi(stem.substr(dash + 1))};
  } catch (const std::exception&) {
    return {stem, 0};
  }
}

fs::path NewestRun(const fs::path& workspace, const std::string& extension) {
  fs::path newest;
  std::error_code ec;
  for (fs::directory_iterator it(workspace / "logs", ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind("run-", 0) == 0 && it->path().extension() == extension &&
        (newest.empty() || RunOrder(it->path()) > RunOrder(newest)))
      newest = it->path();
  }
  return newest;
}

fs::path NewestRunRecord(const fs::path& workspace) { return NewestRun(workspace, ".json"); }

}  // namespace locforge::host

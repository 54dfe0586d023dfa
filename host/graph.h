// YAML graphs: parsing, `${var}` substitution, `--set` overrides and matrix
// expansion (graph.cc), then validation against the stage registry and
// topological ordering (graph_check.cc). Every problem is collected as a
// Diagnostic naming file:line:column and what was expected; nothing throws.
//
//   locforge: 1
//   vars: {count: 8}
//   matrix: {bins: [8, 16]}
//   nodes:
//     images: {stage: source/synthetic_images, params: {count: "${count}"}}
//     stats:  {stage: example/image_stats, inputs: {images: images.dataset},
//              params: {bins: "${bins}"}}
#ifndef LOCFORGE_HOST_GRAPH_H_
#define LOCFORGE_HOST_GRAPH_H_

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "locforge/runtime/registry.h"

namespace locforge::host {

namespace fs = std::filesystem;

// Where a value came from: a graph file position (1-based) or a command-line
// option such as "--set stats.bins=4".
struct SourceLocation {
  std::string file;
  int line = 0;
  int column = 0;
  std::string ToString() const;
};

struct Diagnostic {
  SourceLocation where;
  std::string message;
  std::string ToString() const { return where.ToString() + ": error: " + message; }
};
using Diagnostics = std::vector<Diagnostic>;

struct ComponentParam;

// A value after substitution: a scalar, a list when written as a YAML list,
// or a component written as a mapping {stage: KIND/NAME, params: {...}}.
struct Value {
  std::vector<std::string> items;  // one item for a scalar; the stage id of a component
  bool is_list = false;
  bool is_component = false;
  std::vector<ComponentParam> params;  // a component's parameters, as written
  std::string scalar() const { return items.empty() ? "" : items.front(); }
};

struct ComponentParam {
  std::string name;
  Value value;
  SourceLocation key_where, value_where;
};

struct ParamValue {
  Value value;
  SourceLocation key_where;    // the key (or the --set option)
  SourceLocation value_where;  // the value (or the --set option)
  // Relative PATH values are resolved against this folder: the graph file's
  // folder when written in the graph, the current directory for --set.
  fs::path base_dir;
  bool broken = false;  // substitution failed (already reported): not checked further
};

struct Wire {
  std::string node;
  std::string port;  // empty: the node's only output
  SourceLocation where;
};

struct InputSpec {
  std::vector<Wire> wires;
  bool is_list = false;
  SourceLocation where;  // the port key
  bool broken = false;   // substitution failed (already reported)
};

struct NodeSpec {
  std::string name;
  SourceLocation where;  // the node's key
  std::string stage;
  SourceLocation stage_where;
  std::map<std::string, ParamValue> params;
  std::map<std::string, InputSpec> inputs;
};

struct GraphVariant {
  std::string name;  // "" without a matrix, else "key=value,key=value"
  std::vector<std::pair<std::string, std::string>> matrix_values;
  std::vector<NodeSpec> nodes;  // in file order
};

// One scheduler request of the graph's `slurm:` section (or of a
// `--slurm-opt` option): sbatch option `key` (its long name, e.g.
// cpus-per-task, mem, time, partition) set to `value` for the jobs of the
// nodes `selector` names: `default`, a stage kind, a stage id or a node.
struct SchedulerSetting {
  std::string selector;
  std::string key;
  std::string value;
  SourceLocation where;
};

struct Graph {
  fs::path file;  // absolute
  std::string description;
  std::vector<SchedulerSetting> slurm;  // as written; checked by host/slurm.h
  std::vector<std::pair<fs::path, SourceLocation>> plugin_paths;  // absolute folders
  std::vector<GraphVariant> variants;  // at least one when parsing succeeded
};

// A `--set key=value` option: a graph variable (or matrix key, which pins the
// matrix to that value) when `key` has no dot, else `node.param`.
struct Override {
  std::string key;
  std::string value;
};
// " (did you mean 'x'?)" naming the closest candidate, or "" when none is close.
std::string Hint(const std::string& word, const std::vector<std::string>& candidates);
// "a, b, c", or "none" when empty.
std::string JoinNames(const std::vector<std::string>& names);

// Parses "key=value"; returns false when there is no '='.
bool ParseOverride(const std::string& text, Override* out);

// Parses a graph from text (file names the source in diagnostics and anchors
// relative paths). Returns false and appends diagnostics on any problem.
bool ParseGraph(const std::string& text, const fs::path& file, const std::vector<Override>& sets,
                const fs::path& cwd, Graph* graph, Diagnostics* errors);
bool LoadGraph(const fs::path& file, const std::vector<Override>& sets, Graph* graph,
               Diagnostics* errors);

// ---- Validation (graph_check.cc) -------------------------------------------

using StageLookup = std::map<std::string, const runtime::StageEntry*>;
StageLookup LookupOf(const runtime::Registry& registry);

struct ResolvedInput {
  std::string port;
  std::string artifact_type;
  std::string node;      // upstream node
  std::string out_port;  // its output port
};

struct ResolvedNode {
  std::string name;
  const runtime::StageEntry* stage = nullptr;
  std::map<std::string, std::string> params;  // canonical, defaults filled, PATHs absolute
  // Component parameters: the chosen stage, its version and its parameter values,
  // defaults filled ("kind/name 1.0.0 a=1 b=x"), part of the cache key as the
  // node's results depend on them.
  std::map<std::string, std::string> components;
  std::vector<ResolvedInput> inputs;          // sorted by port name
};

struct ResolvedGraph {
  std::string variant;
  std::vector<ResolvedNode> nodes;  // topological order (file order among ready nodes)
  // Nodes nothing else reads: the graph's final outputs.
  std::vector<std::string> sinks;
};

// Checks one variant against the stages (stage ids, params with the plugin's
// own check, wires, artifact types, required inputs, cycles, PATH existence)
// and orders it. Returns false with diagnostics on any problem.
bool ResolveVariant(const GraphVariant& variant, const StageLookup& stages, ResolvedGraph* out,
                    Diagnostics* errors);

// Keeps the first of identical diagnostics (variants repeat the same ones).
Diagnostics Deduplicate(const Diagnostics& errors);

}  // namespace locforge::host

#endif  // LOCFORGE_HOST_GRAPH_H_

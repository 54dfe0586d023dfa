// Host side of the plugin ABI: loading plugin libraries, the stage registry,
// and running one stage instance (whole or per-item, threaded, sharded,
// resumable). Used by the `locforge` host and by the plugin test kit.
#ifndef LOCFORGE_RUNTIME_REGISTRY_H_
#define LOCFORGE_RUNTIME_REGISTRY_H_

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "locforge/abi.h"
#include "locforge/params.h"

namespace locforge::runtime {

namespace fs = std::filesystem;

struct LoadedPlugin {
  fs::path file;
  const LfPluginInfo* info = nullptr;
  void* handle = nullptr;  // dlopen handle; never closed (plugins are not unloaded)
};

// The C++ form of one LfPortSpec.
struct PortDecl {
  std::string name;
  std::string artifact_type;
  uint32_t flags = 0;  // LF_PORT_OPTIONAL | LF_PORT_MULTIPLE
  std::string doc;
};

struct StageEntry {
  std::string id;  // "kind/name"
  // The version keying the stage's results: its own (LfStageInfo::version)
  // when it declares one, else its plugin's.
  std::string version;
  bool own_version = false;
  const LfStageInfo* info = nullptr;
  const LoadedPlugin* plugin = nullptr;
  std::vector<ParamDecl> params;  // the C++ form of info->params
  // The C++ form of info->inputs / info->outputs. Use these rather than
  // indexing the C arrays: a newer plugin's structs may be larger.
  std::vector<PortDecl> inputs;
  std::vector<PortDecl> outputs;

  bool runnable() const { return (info->flags & LF_STAGE_RUNNABLE) != 0; }
  bool per_item() const { return (info->flags & LF_STAGE_PER_ITEM) != 0; }
  bool is_component() const { return info->component_interface != nullptr; }
};

// A library that was refused, and why (shown by `plugins list`; it is skipped).
struct PluginProblem {
  fs::path file;
  std::string message;
};

class Registry {
 public:
  Registry();
  ~Registry();  // does not unload anything
  Registry(const Registry&) = delete;
  Registry& operator=(const Registry&) = delete;

  // Plugin folders searched by default, in order: the build's plugin folder,
  // the install's lib/locforge/plugins (relative to the executable), then
  // each folder of $LOCFORGE_PLUGIN_PATH (':'-separated). Missing folders are
  // skipped, duplicates removed. With LOCFORGE_NO_DEFAULT_PLUGINS=1 only
  // $LOCFORGE_PLUGIN_PATH is used (tests use it to isolate themselves).
  static std::vector<fs::path> DefaultSearchPath();

  // Loads every shared library (*.so) directly inside `folder`, sorted by name.
  // A missing folder loads nothing.
  void LoadFolder(const fs::path& folder);
  // LoadFolder on each, in order (e.g. DefaultSearchPath()).
  void LoadFolders(const std::vector<fs::path>& folders);
  // Loads one library. A broken one (not loadable, no entry point, wrong ABI
  // version or struct size, entry returning NULL, malformed metadata) is
  // recorded in problems() and skipped. Returns true when loaded.
  bool LoadFile(const fs::path& file);

  const StageEntry* Find(const std::string& id) const;
  std::vector<const StageEntry*> Stages() const;  // sorted by id
  std::vector<std::string> StageIds() const;
  const std::vector<std::unique_ptr<LoadedPlugin>>& plugins() const { return plugins_; }
  const std::vector<PluginProblem>& problems() const { return problems_; }
  // One message per stage id provided by two libraries, naming both files.
  const std::vector<std::string>& duplicates() const { return duplicates_; }

 private:
  std::vector<std::unique_ptr<LoadedPlugin>> plugins_;
  std::map<std::string, std::unique_ptr<StageEntry>> stages_;
  std::vector<PluginProblem> problems_;
  std::vector<std::string> duplicates_;
};

// Resolves and validates parameters with the declarations, then with the
// plugin's own check_params (its Options::Check()), without creating the
// stage. Throws ParamError naming the stage and parameter.
std::map<std::string, std::string> CheckStageParams(
    const StageEntry& stage, const std::vector<std::pair<std::string, std::string>>& given);

struct InputArtifact {
  std::string port;
  std::string artifact_type;
  fs::path path;
};

// Everything a stage run needs from the host.
struct RunOptions {
  fs::path workspace;
  fs::path output_dir;   // created if missing
  std::vector<InputArtifact> inputs;
  int threads = 1;
  int shard_index = 0;
  int shard_count = 1;
  // Per-item stages keep journals of finished items here, one per shard, so a
  // killed or sharded run resumes where it stopped. Default: output_dir.
  // Files: `.items-done.<shard_index>-of-<shard_count>`, one item id a line.
  // An item belongs to shard FNV-1a-64(item id) % shard_count.
  fs::path journal_dir;
  std::function<void(int level, const std::string& message)> log;
  std::function<void(uint64_t done, uint64_t total, const std::string& what)> progress;
  const std::atomic<bool>* cancel = nullptr;
};

struct RunResult {
  // False when this shard finished its items but others are still pending,
  // so finalize did not run yet.
  bool complete = false;
  uint64_t items_total = 0;     // per-item stages: items of this shard
  uint64_t items_processed = 0; // processed by this call
  uint64_t items_resumed = 0;   // found done in journals
  double seconds = 0;
};

// One created stage. Destroys the plugin instance on destruction.
class StageInstance {
 public:
  // Creates the stage with resolved parameters; throws ParamError or Error.
  StageInstance(const StageEntry& stage, const std::map<std::string, std::string>& params);
  ~StageInstance();
  StageInstance(const StageInstance&) = delete;
  StageInstance& operator=(const StageInstance&) = delete;

  // Runs it (whole-stage run, or list/process/finalize for per-item stages
  // with a thread pool of options.threads). Throws Error with the plugin's
  // message on failure; a failing item fails the run after the others finish
  // (finished items stay journaled, so a rerun retries only the failed ones).
  // Throws Cancelled when options.cancel was raised.
  // Per-item: items already in a journal of any shard are skipped; finalize
  // runs in the call that finds every item of every shard journaled (two
  // shards finishing at the same moment may both run it: it must be
  // idempotent, which atomic writes give). Parallel items get threads = 1
  // each; a lone worker (LF_STAGE_SERIAL_ITEMS, or one item) gets them all.
  RunResult Run(const RunOptions& options);

  // In-process component function table (e.g. LfRegistrationInterface), or
  // nullptr when the stage has none.
  const void* Component() const;
  const StageEntry& stage() const { return stage_; }
  void* raw() const { return instance_; }

 private:
  const StageEntry& stage_;
  void* instance_ = nullptr;
};

// The registry whose stages can be created as components from inside a run
// (LfRunContext::create_component). The host sets it once at start.
void SetComponentRegistry(const Registry* registry);

// The shard an item belongs to (FNV-1a 64 of its id, modulo shard_count).
int ShardOfItem(const std::string& item, int shard_count);

}  // namespace locforge::runtime

#endif  // LOCFORGE_RUNTIME_REGISTRY_H_

// Running one stage instance: a whole-stage `run`, or a per-item stage's
// list/process/finalize on a thread pool, split across shards, resumable from
// journals of finished items. Components (stages used in-process by other
// stages) are created through the same code path.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <deque>
#include <mutex>
#include <set>
#include <thread>

#include "journal.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/runtime/registry.h"
#include "plugin_call.h"

namespace locforge::runtime {

using internal::CallPlugin;
using internal::CallStatus;
using internal::ThrowStatus;

namespace {

std::atomic<const Registry*> g_component_registry{nullptr};

void CopyMessage(LfError* err, const std::string& message) noexcept {
  if (err == nullptr) return;
  const size_t n = std::min(message.size(), sizeof(err->message) - 1);
  std::memcpy(err->message, message.data(), n);
  err->message[n] = '\0';
}

// Parameters in the ABI's form; points into `params`, which must outlive it.
std::vector<LfParam> ToLfParams(const std::map<std::string, std::string>& params) {
  std::vector<LfParam> out;
  for (const auto& [name, value] : params) out.push_back({name.c_str(), value.c_str()});
  return out;
}

// Creates a plugin instance; throws with the plugin's message when it fails.
void* CreateInstance(const StageEntry& stage, const std::map<std::string, std::string>& params) {
  const auto lf = ToLfParams(params);
  void* instance = nullptr;
  const CallStatus s = CallPlugin([&](LfError* err) {
    instance = stage.info->create(lf.data(), static_cast<uint32_t>(lf.size()), err);
    return instance ? LF_OK : LF_ERROR;
  });
  if (!s.ok() || instance == nullptr) ThrowStatus(stage.id + ": cannot create the stage", s);
  return instance;
}

void DestroyInstance(const StageEntry& stage, void* instance) noexcept {
  if (instance == nullptr) return;
  try {
    stage.info->destroy(instance);
  } catch (...) {
    // A destructor that throws through the ABI: nothing sensible is left to do.
  }
}

// ---- Host callbacks of LfRunContext (called by plugin code: must not throw).

struct HostState {
  const RunOptions* options = nullptr;
  std::mutex mutex;               // serialises log and progress callbacks
  bool plugin_progress = true;    // per-item stages: the host reports progress itself
};

void LogCallback(void* host, int32_t level, const char* message) {
  auto* h = static_cast<HostState*>(host);
  if (h == nullptr || !h->options->log || message == nullptr) return;
  try {
    std::lock_guard<std::mutex> lock(h->mutex);
    h->options->log(level, message);
  } catch (...) {
  }
}

void ProgressCallback(void* host, uint64_t done, uint64_t total, const char* what) {
  auto* h = static_cast<HostState*>(host);
  if (h == nullptr || !h->plugin_progress || !h->options->progress) return;
  try {
    std::lock_guard<std::mutex> lock(h->mutex);
    h->options->progress(done, total, what ? what : "");
  } catch (...) {
  }
}

int32_t CancelledCallback(void* host) {
  auto* h = static_cast<HostState*>(host);
  return h && h->options->cancel && h->options->cancel->load() ? 1 : 0;
}

void* CreateComponentCallback(void* /*host*/, const char* stage_id, const LfParam* params,
                              uint32_t num_params, const LfStageInfo** info, LfError* err) {
  try {
    if (info) *info = nullptr;
    const Registry* registry = g_component_registry.load();
    if (registry == nullptr)
      throw Error("no component registry (the host did not call SetComponentRegistry)");
    if (stage_id == nullptr) throw Error("component stage id is NULL");
    const StageEntry* stage = registry->Find(stage_id);
    if (stage == nullptr) {
      std::vector<std::string> components;
      for (const auto* s : registry->Stages())
        if (s->is_component()) components.push_back(s->id);
      const std::string hint = DidYouMean(stage_id, components);
      throw Error("unknown component stage '" + std::string(stage_id) + "'" +
                  (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
    }
    if (!stage->is_component())
      throw Error("stage '" + stage->id + "' is not a component (it has no component interface)");
    std::vector<std::pair<std::string, std::string>> given;
    for (uint32_t i = 0; i < num_params; ++i) {
      if (params[i].name == nullptr) throw Error("component parameter #" + std::to_string(i) +
                                                 " has a NULL name");
      given.emplace_back(params[i].name, params[i].value ? params[i].value : "");
    }
    void* instance = CreateInstance(*stage, CheckStageParams(*stage, given));
    if (info) *info = stage->info;
    return instance;
  } catch (const std::exception& e) {
    CopyMessage(err, e.what());
  } catch (...) {
    CopyMessage(err, "unknown error while creating a component");
  }
  return nullptr;
}

void DestroyComponentCallback(void* /*host*/, const LfStageInfo* info, void* instance) {
  if (info == nullptr || instance == nullptr || info->destroy == nullptr) return;
  try {
    info->destroy(instance);
  } catch (...) {
  }
}

// The strings and arrays an LfRunContext points into, for one run.
class ContextData {
 public:
  explicit ContextData(const RunOptions& o)
      : workspace_(o.workspace.string()), output_dir_(o.output_dir.string()) {
    state_.options = &o;
    for (const auto& in : o.inputs) {
      ports_.push_back(in.port);
      types_.push_back(in.artifact_type);
      paths_.push_back(in.path.string());
    }
    for (size_t i = 0; i < ports_.size(); ++i)
      artifacts_.push_back({ports_[i].c_str(), types_[i].c_str(), paths_[i].c_str()});
  }

  LfRunContext Make(int threads) {
    const RunOptions& o = *state_.options;
    LfRunContext c{};
    c.struct_size = sizeof(LfRunContext);
    c.workspace = workspace_.c_str();
    c.output_dir = output_dir_.c_str();
    c.inputs = artifacts_.empty() ? nullptr : artifacts_.data();
    c.num_inputs = static_cast<uint32_t>(artifacts_.size());
    c.threads = std::max(1, threads);
    c.shard_index = o.shard_index;
    c.shard_count = o.shard_count;
    c.host = &state_;
    c.log = &LogCallback;
    c.progress = &ProgressCallback;
    c.cancelled = &CancelledCallback;
    c.create_component = &CreateComponentCallback;
    c.destroy_component = &DestroyComponentCallback;
    return c;
  }

  HostState& state() { return state_; }

 private:
  std::string workspace_, output_dir_;
  std::deque<std::string> ports_, types_, paths_;
  std::vector<LfArtifact> artifacts_;
  HostState state_;
};

bool IsCancelled(const RunOptions& o) { return o.cancel && o.cancel->load(); }

struct ItemFailure {
  std::string item;
  CallStatus status;
};

// The failed items of a run: failures.txt in the journal folder
// (failures.I-of-N.txt for shard I of N), "item, reason" per line.
fs::path ItemFailuresPath(const fs::path& dir, int shard_index, int shard_count) {
  if (shard_count <= 1) return dir / "failures.txt";
  return dir / ("failures." + std::to_string(shard_index) + "-of-" + std::to_string(shard_count) +
                ".txt");
}

// Failure lists of earlier attempts: moot once every item is done.
void RemoveItemFailureLists(const fs::path& dir) {
  std::error_code ec;
  std::vector<fs::path> lists;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const bool shard_list = name.rfind("failures.", 0) == 0 &&
                            name.find("-of-") != std::string::npos && name.size() > 4 &&
                            name.compare(name.size() - 4, 4, ".txt") == 0;
    if (name == "failures.txt" || shard_list) lists.push_back(it->path());
  }
  for (const fs::path& list : lists) fs::remove(list, ec);
}

// Sorts `failures` and lists them at `file` (best effort: the error thrown
// next names the items anyway).
void WriteItemFailures(const fs::path& file, std::vector<ItemFailure>* failures) {
  std::sort(failures->begin(), failures->end(),
            [](const ItemFailure& a, const ItemFailure& b) { return a.item < b.item; });
  std::string text = "# item, reason\n";
  for (const ItemFailure& f : *failures) {
    std::string reason = f.status.message;
    std::replace(reason.begin(), reason.end(), '\n', ' ');
    text += f.item + ", " + reason + "\n";
  }
  try {
    WriteFileAtomic(file, text);
  } catch (const std::exception&) {
  }
}

[[noreturn]] void ThrowItemFailures(const std::string& stage_id, std::vector<ItemFailure> failures,
                                    uint64_t attempted, const fs::path& list) {
  WriteItemFailures(list, &failures);
  constexpr size_t kShown = 5;
  std::string message = stage_id + ": " + std::to_string(failures.size()) + " of " +
                        std::to_string(attempted) + " items failed";
  for (size_t i = 0; i < failures.size() && i < kShown; ++i)
    message += (i ? "; " : ": ") + std::string("item '") + failures[i].item + "': " +
               failures[i].status.message;
  if (failures.size() > kShown)
    message += "; and " + std::to_string(failures.size() - kShown) + " more";
  message += " (all listed in " + list.string() +
             "; finished items are journaled; rerun to retry only the failed ones)";
  const bool all_input = std::all_of(failures.begin(), failures.end(), [](const ItemFailure& f) {
    return f.status.code == LF_BAD_INPUT;
  });
  if (all_input) throw InputError(message);
  throw Error(message);
}

// Emits from list_items (plugin code calls it: must not throw).
struct ItemList {
  std::vector<std::string> items;
  bool null_item = false;
  bool out_of_memory = false;
};

void EmitItem(void* user, const char* item) {
  auto* list = static_cast<ItemList*>(user);
  if (item == nullptr) {
    list->null_item = true;
    return;
  }
  try {
    list->items.emplace_back(item);
  } catch (...) {
    list->out_of_memory = true;
  }
}

std::vector<std::string> ListItems(const StageEntry& stage, void* instance, ContextData* data,
                                   int threads) {
  ItemList list;
  const LfRunContext ctx = data->Make(threads);
  const CallStatus s = CallPlugin([&](LfError* err) {
    return stage.info->list_items(instance, &ctx, &EmitItem, &list, err);
  });
  if (!s.ok()) ThrowStatus(stage.id + ": listing items", s);
  if (list.null_item) throw Error(stage.id + ": list_items emitted a NULL item");
  if (list.out_of_memory) throw Error(stage.id + ": out of memory while listing items");
  std::vector<std::string> sorted = list.items;
  std::sort(sorted.begin(), sorted.end());
  for (size_t i = 0; i < sorted.size(); ++i) {
    // Ids are journal lines: they must be non-empty and single-line.
    if (sorted[i].empty()) throw Error(stage.id + ": list_items emitted an empty item id");
    if (sorted[i].find_first_of("\r\n") != std::string::npos)
      throw Error(stage.id + ": item id '" + sorted[i] + "' contains a line break");
    if (i > 0 && sorted[i] == sorted[i - 1])
      throw Error(stage.id + ": list_items emitted item '" + sorted[i] +
                  "' twice; item ids must be unique");
  }
  return list.items;
}

// This shard's items not journaled yet (result: its item counts).
std::vector<std::string> PendingItems(const std::vector<std::string>& all_items, const fs::path& journal_dir,
                                      const RunOptions& o, RunResult* result) {
  const std::set<std::string> done = internal::ReadJournals(journal_dir);
  std::vector<std::string> pending;
  for (const auto& item : all_items) {
    if (ShardOfItem(item, o.shard_count) != o.shard_index) continue;
    ++result->items_total;
    if (done.count(item)) ++result->items_resumed;
    else pending.push_back(item);
  }
  return pending;
}

// The pending items processed side by side, each journaled once done.
struct ItemWork {
  const StageEntry& stage;
  void* instance;
  const RunOptions& o;
  ContextData* data;
  const std::vector<std::string>& pending;
  const uint64_t total;
  internal::JournalWriter& journal;
  // Guards failures and counters, and serialises progress with log callbacks.
  std::mutex& mutex;
  std::vector<ItemFailure> failures;
  uint64_t finished;
  std::atomic<size_t> next{0};
  std::atomic<uint64_t> processed{0};
  std::atomic<bool> cancelled{false};

  // One item done: journaled and counted (a journal error fails the item).
  void Record(const std::string& item, CallStatus s) {
    if (s.ok()) {
      try {
        journal.Append(item);
      } catch (const std::exception& e) {
        s = {LF_ERROR, e.what()};
      }
    }
    std::lock_guard<std::mutex> lock(mutex);
    if (s.ok()) {
      ++processed;
      ++finished;
      if (o.progress) {
        try {
          o.progress(finished, total, item);
        } catch (...) {
        }
      }
    } else {
      failures.push_back({item, s});
    }
  }

  // A worker: the next pending item until none is left or the run is cancelled.
  void Work(int item_threads) {
    const LfRunContext ctx = data->Make(item_threads);
    while (true) {
      if (IsCancelled(o)) {
        cancelled = true;
        return;
      }
      const size_t i = next.fetch_add(1);
      if (i >= pending.size()) return;
      const std::string& item = pending[i];
      const CallStatus s = CallPlugin([&](LfError* err) {
        return stage.info->process_item(instance, &ctx, item.c_str(), err);
      });
      if (s.code == LF_CANCELLED) {
        cancelled = true;
        return;
      }
      Record(item, s);
    }
  }

  // Parallel items get one thread each; a lone worker may use them all.
  void Run() {
    const bool serial = (stage.info->flags & LF_STAGE_SERIAL_ITEMS) != 0;
    const int workers = static_cast<int>(std::min<size_t>(
        serial ? 1 : static_cast<size_t>(std::max(1, o.threads)), std::max<size_t>(1, pending.size())));
    const int item_threads = workers > 1 ? 1 : std::max(1, o.threads);
    std::vector<std::thread> pool;
    for (int w = 1; w < workers; ++w) pool.emplace_back([this, item_threads] { Work(item_threads); });
    Work(item_threads);
    for (auto& t : pool) t.join();
  }
};

// Finalizes once every item of every shard is journaled (by any shard
// count): false when other shards are still pending.
bool FinalizeWhenAllDone(const StageEntry& stage, void* instance, const RunOptions& o, ContextData* data,
                         const std::vector<std::string>& all_items, const fs::path& journal_dir) {
  const std::set<std::string> done = internal::ReadJournals(journal_dir);
  for (const auto& item : all_items)
    if (!done.count(item)) return false;
  RemoveItemFailureLists(journal_dir);
  const LfRunContext ctx = data->Make(o.threads);
  const CallStatus s = CallPlugin([&](LfError* err) { return stage.info->finalize(instance, &ctx, err); });
  if (!s.ok()) ThrowStatus(stage.id + ": finalize", s);
  return true;
}

RunResult RunPerItem(const StageEntry& stage, void* instance, const RunOptions& o,
                     ContextData* data) {
  data->state().plugin_progress = false;  // progress is counted here, per item
  const fs::path journal_dir = o.journal_dir.empty() ? o.output_dir : o.journal_dir;
  const std::vector<std::string> all_items = ListItems(stage, instance, data, o.threads);
  RunResult result;
  const std::vector<std::string> pending = PendingItems(all_items, journal_dir, o, &result);
  if (o.progress && !pending.empty()) o.progress(result.items_resumed, result.items_total, "");
  std::vector<ItemFailure> failures;
  bool cancelled = false;
  if (!pending.empty()) {
    std::error_code ec;
    fs::remove(ItemFailuresPath(journal_dir, o.shard_index, o.shard_count), ec);  // a retry re-lists
    internal::JournalWriter journal(internal::JournalPath(journal_dir, o.shard_index, o.shard_count));
    ItemWork work{stage, instance, o, data, pending, result.items_total, journal, data->state().mutex, {},
                  result.items_resumed};
    work.Run();
    result.items_processed = work.processed.load();
    failures = std::move(work.failures);
    cancelled = work.cancelled;
  }
  if (!failures.empty())
    ThrowItemFailures(stage.id, std::move(failures), static_cast<uint64_t>(pending.size()),
                      ItemFailuresPath(journal_dir, o.shard_index, o.shard_count));
  if (cancelled) throw Cancelled();
  result.complete = FinalizeWhenAllDone(stage, instance, o, data, all_items, journal_dir);
  return result;
}

}  // namespace

int ShardOfItem(const std::string& item, int shard_count) {
  if (shard_count <= 1) return 0;
  uint64_t h = 14695981039346656037ull;  // FNV-1a 64: stable across builds and platforms
  for (unsigned char c : item) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return static_cast<int>(h % static_cast<uint64_t>(shard_count));
}

void SetComponentRegistry(const Registry* registry) { g_component_registry.store(registry); }

std::map<std::string, std::string> CheckStageParams(
    const StageEntry& stage, const std::vector<std::pair<std::string, std::string>>& given) {
  std::map<std::string, std::string> resolved;
  try {
    resolved = ResolveParams(stage.params, given);
  } catch (const ParamError& e) {
    throw ParamError(stage.id + ": " + e.what());
  }
  const auto lf = ToLfParams(resolved);
  const CallStatus s = CallPlugin([&](LfError* err) {
    return stage.info->check_params(lf.data(), static_cast<uint32_t>(lf.size()), err);
  });
  if (!s.ok()) {
    CallStatus refused = s;
    if (refused.code == LF_ERROR) refused.code = LF_BAD_PARAMS;  // check_params only judges params
    ThrowStatus(stage.id, refused);
  }
  return resolved;
}

StageInstance::StageInstance(const StageEntry& stage,
                             const std::map<std::string, std::string>& params)
    : stage_(stage) {
  instance_ = CreateInstance(stage, params);
}

StageInstance::~StageInstance() { DestroyInstance(stage_, instance_); }

const void* StageInstance::Component() const {
  if (stage_.info->component == nullptr) return nullptr;
  try {
    return stage_.info->component(instance_);
  } catch (...) {
    return nullptr;
  }
}

RunResult StageInstance::Run(const RunOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (options.shard_count < 1 || options.shard_index < 0 ||
      options.shard_index >= options.shard_count)
    throw Error(stage_.id + ": invalid shard " + std::to_string(options.shard_index) + " of " +
                std::to_string(options.shard_count));
  if (!stage_.runnable()) throw Error(stage_.id + ": not runnable (a component only)");
  std::error_code ec;
  fs::create_directories(options.output_dir, ec);
  if (ec) throw Error(stage_.id + ": cannot create " + options.output_dir.string() + ": " +
                      ec.message());

  ContextData data(options);
  RunResult result;
  if (!stage_.per_item()) {
    const LfRunContext ctx = data.Make(options.threads);
    const CallStatus s =
        CallPlugin([&](LfError* err) { return stage_.info->run(instance_, &ctx, err); });
    if (!s.ok()) ThrowStatus(stage_.id, s);
    result.complete = true;
  } else {
    result = RunPerItem(stage_, instance_, options, &data);
  }
  result.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace locforge::runtime

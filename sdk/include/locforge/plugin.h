// Writing a plugin in C++: derive stages from locforge::Stage or
// locforge::PerItemStage, give each a static Meta(), and list them in
// LOCFORGE_PLUGIN(...). This header turns them into the C ABI of abi.h:
// it builds the static metadata, and wraps every call so that exceptions
// become LfError statuses and never cross into the host.
//
//   class Blur : public locforge::PerItemStage<BlurOptions> {
//    public:
//     static locforge::StageMeta Meta() {
//       locforge::StageMeta m{"example", "blur", "Blurs every image",
//                             {{"images", "kapture.dataset"}}, {{"images", "kapture.dataset"}}};
//       m.version = "1.0.0";  // optional: the stage's own version
//       return m;
//     }
//     using PerItemStage::PerItemStage;
//     std::vector<std::string> ListItems(locforge::RunContext& ctx) override;
//     void ProcessItem(locforge::RunContext& ctx, const std::string& item) override;
//   };
//   LOCFORGE_PLUGIN("examples", "1.0.0", "Example stages", Blur)
#ifndef LOCFORGE_PLUGIN_H_
#define LOCFORGE_PLUGIN_H_

#include <deque>
#include <filesystem>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "locforge/abi.h"
#include "locforge/error.h"
#include "locforge/params.h"
#include "locforge/version.h"

namespace locforge {

struct PortMeta {
  std::string name;
  std::string artifact_type;
  std::string doc;
  uint32_t flags = 0;  // LF_PORT_OPTIONAL | LF_PORT_MULTIPLE
};

struct StageMeta {
  std::string kind;
  std::string name;
  std::string doc;
  std::vector<PortMeta> inputs;
  std::vector<PortMeta> outputs;
  uint32_t flags = 0;  // extra LF_STAGE_* flags (SERIAL_ITEMS, NONDETERMINISTIC)
  // The stage's own version: bump it when its results change. It enters the
  // cache keys of its results instead of the plugin's version, so the other
  // stages of the plugin keep their cached results. Empty: the plugin's.
  std::string version = {};
};

// C++ view of LfRunContext, handed to Run/ListItems/ProcessItem/Finalize.
class RunContext {
 public:
  explicit RunContext(const LfRunContext* c) : c_(c) {}

  std::filesystem::path workspace() const { return c_->workspace; }
  std::filesystem::path output_dir() const { return c_->output_dir; }
  int threads() const { return c_->threads > 0 ? c_->threads : 1; }
  int shard_index() const { return c_->shard_index; }
  int shard_count() const { return c_->shard_count > 0 ? c_->shard_count : 1; }

  bool HasInput(const std::string& port) const { return !Inputs(port).empty(); }
  // All artifacts wired to `port` (several for LF_PORT_MULTIPLE).
  std::vector<std::filesystem::path> Inputs(const std::string& port) const {
    std::vector<std::filesystem::path> out;
    for (uint32_t i = 0; i < c_->num_inputs; ++i)
      if (port == c_->inputs[i].port) out.emplace_back(c_->inputs[i].path);
    return out;
  }
  // The one artifact wired to `port`; throws when absent.
  std::filesystem::path Input(const std::string& port) const {
    auto all = Inputs(port);
    if (all.empty()) throw Error("input port '" + port + "' is not wired");
    return all.front();
  }

  // A folder a stage takes either as a PATH parameter or as an input
  // artifact wired in the graph: e.g. a recording, given as the `dataset`
  // parameter or wired to the `recording` input from source/simulator. Throws
  // ParamError naming `stage`, the parameter and the port when neither or
  // both are given.
  std::filesystem::path PathOrInput(const std::string& stage, const std::string& param,
                                    const std::string& value, const std::string& port) const {
    if (HasInput(port)) {
      if (!value.empty())
        throw ParamError(stage + ": given twice: as the " + param + " parameter (" + value + ") and as the " +
                         port + " input; keep one");
      return Input(port);
    }
    if (value.empty())
      throw ParamError(stage + ": no " + param + ": set the " + param + " parameter (in the shipped graphs: --set " +
                       param + "=DIR) or wire the " + port + " input");
    return value;
  }

  void Debug(const std::string& m) const { Log(LF_LOG_DEBUG, m); }
  void Info(const std::string& m) const { Log(LF_LOG_INFO, m); }
  void Warn(const std::string& m) const { Log(LF_LOG_WARNING, m); }
  void Progress(uint64_t done, uint64_t total, const std::string& what = "") const {
    if (c_->progress) c_->progress(c_->host, done, total, what.c_str());
  }
  bool cancelled() const { return c_->cancelled && c_->cancelled(c_->host) != 0; }
  void ThrowIfCancelled() const {
    if (cancelled()) throw Cancelled();
  }

  const LfRunContext* raw() const { return c_; }

 private:
  void Log(int32_t level, const std::string& m) const {
    if (c_->log) c_->log(c_->host, level, m.c_str());
  }
  const LfRunContext* c_;
};

// A stage that runs once per graph node.
template <typename OptionsT>
class Stage {
 public:
  using Options = OptionsT;
  explicit Stage(Options options) : options_(std::move(options)) {}
  virtual ~Stage() = default;
  virtual void Run(RunContext& ctx) = 0;
  const Options& options() const { return options_; }

 private:
  Options options_;
};

// A stage whose work splits into independent items (images, pairs, queries,
// scans). The host runs ProcessItem in parallel and across shards; it must be
// thread-safe unless Meta() sets LF_STAGE_SERIAL_ITEMS, and write each item's
// output atomically (locforge/fs.h). Finalize runs once all items are done.
template <typename OptionsT>
class PerItemStage {
 public:
  using Options = OptionsT;
  explicit PerItemStage(Options options) : options_(std::move(options)) {}
  virtual ~PerItemStage() = default;
  virtual std::vector<std::string> ListItems(RunContext& ctx) = 0;
  virtual void ProcessItem(RunContext& ctx, const std::string& item) = 0;
  virtual void Finalize(RunContext& /*ctx*/) {}
  const Options& options() const { return options_; }

 private:
  Options options_;
};

// A stage usable in-process by other stages through an interface of abi.h
// (e.g. LF_REGISTRATION_INTERFACE). Implement `const void* Table()` to return
// the interface's static function table.
template <typename OptionsT>
class Component {
 public:
  using Options = OptionsT;
  explicit Component(Options options) : options_(std::move(options)) {}
  virtual ~Component() = default;
  const Options& options() const { return options_; }

 private:
  Options options_;
};

namespace internal {

void WriteError(LfError* err, const std::string& message) noexcept;

// Runs `f`, turning any exception into a status and message.
template <typename F>
int32_t Guard(LfError* err, F&& f) noexcept {
  try {
    f();
    return LF_OK;
  } catch (const Error& e) {
    if (err) WriteError(err, e.what());
    return e.code();
  } catch (const std::exception& e) {
    if (err) WriteError(err, e.what());
    return LF_ERROR;
  } catch (...) {
    if (err) WriteError(err, "unknown exception in plugin");
    return LF_ERROR;
  }
}

inline std::vector<std::pair<std::string, std::string>> ToPairs(const LfParam* p, uint32_t n) {
  std::vector<std::pair<std::string, std::string>> out;
  for (uint32_t i = 0; i < n; ++i) out.emplace_back(p[i].name, p[i].value ? p[i].value : "");
  return out;
}

template <typename S>
using OptionsOf = typename S::Options;

template <typename S>
constexpr bool kIsPerItem = std::is_base_of_v<PerItemStage<OptionsOf<S>>, S>;
template <typename S>
constexpr bool kIsWhole = std::is_base_of_v<Stage<OptionsOf<S>>, S>;
template <typename S>
constexpr bool kIsComponent = std::is_base_of_v<Component<OptionsOf<S>>, S>;

template <typename S>
struct Adapter {
  static const ParamSchema<OptionsOf<S>>& Schema() {
    static const ParamSchema<OptionsOf<S>> schema;
    return schema;
  }
  static int32_t CheckParams(const LfParam* p, uint32_t n, LfError* err) {
    return Guard(err, [&] { (void)Schema().Parse(ToPairs(p, n)); });
  }
  static void* Create(const LfParam* p, uint32_t n, LfError* err) {
    S* out = nullptr;
    const int32_t rc = Guard(err, [&] { out = new S(Schema().Parse(ToPairs(p, n))); });
    return rc == LF_OK ? out : nullptr;
  }
  static void Destroy(void* instance) {
    try {
      delete static_cast<S*>(instance);
    } catch (...) {
    }
  }
  static int32_t Run(void* instance, const LfRunContext* c, LfError* err) {
    return Guard(err, [&] {
      if constexpr (kIsWhole<S>) {
        RunContext ctx(c);
        static_cast<S*>(instance)->Run(ctx);
      }
    });
  }
  static int32_t ListItems(void* instance, const LfRunContext* c, LfEmitItem emit, void* user,
                           LfError* err) {
    return Guard(err, [&] {
      if constexpr (kIsPerItem<S>) {
        RunContext ctx(c);
        for (const auto& item : static_cast<S*>(instance)->ListItems(ctx))
          emit(user, item.c_str());
      }
    });
  }
  static int32_t ProcessItem(void* instance, const LfRunContext* c, const char* item,
                             LfError* err) {
    return Guard(err, [&] {
      if constexpr (kIsPerItem<S>) {
        RunContext ctx(c);
        static_cast<S*>(instance)->ProcessItem(ctx, item);
      }
    });
  }
  static int32_t Finalize(void* instance, const LfRunContext* c, LfError* err) {
    return Guard(err, [&] {
      if constexpr (kIsPerItem<S>) {
        RunContext ctx(c);
        static_cast<S*>(instance)->Finalize(ctx);
      }
    });
  }
  static const void* ComponentTable(void* instance) {
    if constexpr (kIsComponent<S>) {
      try {
        return static_cast<S*>(instance)->Table();
      } catch (...) {
        return nullptr;
      }
    }
    return nullptr;
  }
};

// Owns the static metadata of one plugin: every pointer in the LfPluginInfo
// it returns points into this object, which lives until the process exits.
class PluginBuilder {
 public:
  PluginBuilder(const char* name, const char* version, const char* description);

  template <typename S>
  void AddStage() {
    static_assert(kIsWhole<S> || kIsPerItem<S> || kIsComponent<S>,
                  "a stage derives from Stage, PerItemStage or Component");
    LfStageInfo info{};
    info.struct_size = sizeof(LfStageInfo);
    info.check_params = &Adapter<S>::CheckParams;
    info.create = &Adapter<S>::Create;
    info.destroy = &Adapter<S>::Destroy;
    uint32_t flags = 0;
    if constexpr (kIsWhole<S>) {
      flags |= LF_STAGE_RUNNABLE;
      info.run = &Adapter<S>::Run;
    }
    if constexpr (kIsPerItem<S>) {
      flags |= LF_STAGE_RUNNABLE | LF_STAGE_PER_ITEM;
      info.list_items = &Adapter<S>::ListItems;
      info.process_item = &Adapter<S>::ProcessItem;
      info.finalize = &Adapter<S>::Finalize;
    }
    const char* iface = nullptr;
    if constexpr (kIsComponent<S>) {
      iface = S::kInterface;
      info.component = &Adapter<S>::ComponentTable;
    }
    AddStageInfo(info, S::Meta(), Adapter<S>::Schema().Decls(), flags, iface);
  }

  const LfPluginInfo* Finish();

 private:
  void AddStageInfo(LfStageInfo info, const StageMeta& meta, const std::vector<ParamDecl>& params,
                    uint32_t flags, const char* iface);
  const char* Keep(const std::string& s);

  std::deque<std::string> strings_;
  std::deque<std::vector<LfParamSpec>> param_specs_;
  std::deque<std::vector<LfPortSpec>> port_specs_;
  std::vector<LfStageInfo> stages_;
  LfPluginInfo info_{};
};

using StageAdder = void (*)(PluginBuilder&);

// The stages the plugin's files registered with LOCFORGE_REGISTER_STAGE, in
// link order. LOCFORGE_PLUGIN defines it once per plugin; hidden, so that
// every plugin keeps its own list whatever the loader's symbol scope.
__attribute__((visibility("hidden"))) std::vector<StageAdder>& RegisteredStages();

struct StageRegistrar {
  explicit StageRegistrar(StageAdder add) { RegisteredStages().push_back(add); }
};

template <typename S>
void AddStageOf(PluginBuilder& builder) {
  builder.template AddStage<S>();
}

template <typename... Stages>
const LfPluginInfo* BuildPlugin(const char* name, const char* version, const char* description) {
  // Built once; never freed, as plugins are never unloaded.
  static const LfPluginInfo* info = [&] {
    auto* builder = new PluginBuilder(name, version, description);
    (builder->template AddStage<Stages>(), ...);
    for (StageAdder add : RegisteredStages()) add(*builder);
    return builder->Finish();
  }();
  return info;
}

}  // namespace internal

}  // namespace locforge

// Registers a stage with the plugin its file is linked into, where the stage
// is defined: adding a stage is its file plus its line in the plugin's
// SOURCES. The plugin lists registered stages in link order, after those
// LOCFORGE_PLUGIN names.
//   class PairsFileStage : public locforge::Stage<PairsFileOptions> { ... };
//   LOCFORGE_REGISTER_STAGE(PairsFileStage)
#define LOCFORGE_REGISTER_STAGE(STAGE) LOCFORGE_REGISTER_STAGE_N(STAGE, __COUNTER__)
#define LOCFORGE_REGISTER_STAGE_N(STAGE, N) LOCFORGE_REGISTER_STAGE_NN(STAGE, N)
#define LOCFORGE_REGISTER_STAGE_NN(STAGE, N)                          \
  static const ::locforge::internal::StageRegistrar locforge_stage_registrar_##N( \
      &::locforge::internal::AddStageOf<STAGE>);

// Defines the plugin's single exported entry point and its list of
// registered stages. The stages: those named here (classes visible in this
// file), then those registered by the plugin's files (LOCFORGE_REGISTER_STAGE).
#define LOCFORGE_PLUGIN(NAME, VERSION, DESCRIPTION, ...)                                   \
  std::vector<::locforge::internal::StageAdder>& ::locforge::internal::RegisteredStages() { \
    static std::vector<::locforge::internal::StageAdder> stages;                         \
    return stages;                                                                       \
  }                                                                                      \
  extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t host_abi) {      \
    if (host_abi != LF_ABI_VERSION) return nullptr;                                      \
    try {                                                                                \
      return ::locforge::internal::BuildPlugin<__VA_ARGS__>(NAME, VERSION, DESCRIPTION);   \
    } catch (...) {                                                                      \
      return nullptr;                                                                    \
    }                                                                                    \
  }

#endif  // LOCFORGE_PLUGIN_H_

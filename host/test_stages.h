// Fake stages for the host's unit tests: a registry-free StageLookup whose
// entries carry real LfStageInfo/LfPluginInfo structs, so graph validation
// and cache keys run exactly as with a loaded plugin.
#ifndef LOCFORGE_HOST_TEST_STAGES_H_
#define LOCFORGE_HOST_TEST_STAGES_H_

#include <cstring>
#include <deque>
#include <string>
#include <vector>

#include "graph.h"

namespace locforge::host::testing {

// Refuses "mode=bad" like an Options::Check() would.
inline int32_t FakeCheck(const LfParam* params, uint32_t n, LfError* err) {
  for (uint32_t i = 0; i < n; ++i)
    if (std::string(params[i].name) == "mode" && std::string(params[i].value) == "bad") {
      std::snprintf(err->message, sizeof(err->message), "mode 'bad' is refused by Check()");
      return LF_BAD_PARAMS;
    }
  return LF_OK;
}

class FakeStages {
 public:
  FakeStages() {
    plugin_info_.abi_version = LF_ABI_VERSION;
    plugin_info_.struct_size = sizeof(LfPluginInfo);
    plugin_info_.name = "fake";
    plugin_info_.version = "1.0.0";
    plugin_info_.sdk_version = "0.1.0";
    plugin_.file = "/fake/libfake.so";
    plugin_.info = &plugin_info_;

    ParamDecl count{"count", LF_PARAM_INT, 0, "8", "images"};
    count.has_min = true;
    count.min_value = 1;
    ParamDecl verbose{"verbose", LF_PARAM_BOOL, LF_PARAM_NO_CACHE_KEY, "false", "chatty"};
    ParamDecl root{"root", LF_PARAM_PATH, LF_PARAM_REQUIRED, "", "input folder"};
    ParamDecl mode{"mode", LF_PARAM_ENUM, 0, "fast", "speed"};
    mode.choices = {"fast", "bad", "slow"};
    ParamDecl scales{"scales", LF_PARAM_DOUBLE_LIST, 0, "1", "scales"};
    Add("source/images", LF_STAGE_RUNNABLE, {count, verbose, mode}, {},
        {{"images", "kapture.dataset"}});
    Add("source/folder", LF_STAGE_RUNNABLE, {root}, {}, {{"images", "kapture.dataset"}});
    // A preset-driven source: "width" defaults to the preset's ("" = not given).
    ParamDecl width{"width", LF_PARAM_DOUBLE, LF_PARAM_DERIVED, "", "width (default: the preset's)"};
    width.has_min = true;
    width.min_value = 1;
    Add("source/preset", LF_STAGE_RUNNABLE, {width}, {}, {{"images", "kapture.dataset"}});
    Add("features/sift", LF_STAGE_RUNNABLE | LF_STAGE_PER_ITEM, {count, scales},
        {{"images", "kapture.dataset"}}, {{"features", "kapture.features"}});
    Add("match/pairs", LF_STAGE_RUNNABLE, {},
        {{"features", "kapture.features"}, {"extra", "kapture.features", LF_PORT_OPTIONAL}},
        {{"matches", "kapture.matches"}});
    Add("filter/features", LF_STAGE_RUNNABLE, {},
        {{"features", "kapture.features", LF_PORT_MULTIPLE}}, {{"features", "kapture.features"}});
    Add("registration/icp", 0, {}, {}, {});
    // A component with an interface and parameters, and a stage choosing it.
    ParamDecl iterations{"iterations", LF_PARAM_INT, 0, "10", "iterations"};
    iterations.has_min = iterations.has_max = true;
    iterations.min_value = 1;
    iterations.max_value = 100;
    Add("registration/fake_icp", 0, {iterations, mode}, {}, {}, LF_REGISTRATION_INTERFACE, "2.0.0");
    Add("registration/other", 0, {}, {}, {}, "locforge.other/1");
    ParamDecl backend{"backend", LF_PARAM_COMPONENT, 0, "registration/fake_icp", "back-end"};
    backend.component_interface = LF_REGISTRATION_INTERFACE;
    Add("slam/graph", LF_STAGE_RUNNABLE, {backend}, {}, {{"poses", "kapture.trajectories"}});
  }

  const StageLookup& lookup() const { return lookup_; }
  const runtime::StageEntry* Find(const std::string& id) const { return lookup_.at(id); }
  LfPluginInfo& plugin_info() { return plugin_info_; }
  runtime::StageEntry& Entry(const std::string& id) { return *const_cast<runtime::StageEntry*>(lookup_.at(id)); }

 private:
  void Add(const std::string& id, uint32_t flags, std::vector<ParamDecl> params,
           std::vector<runtime::PortDecl> inputs, std::vector<runtime::PortDecl> outputs,
           const char* component_interface = nullptr, const char* version = nullptr) {
    infos_.emplace_back();
    LfStageInfo& info = infos_.back();
    info.struct_size = sizeof(LfStageInfo);
    info.flags = flags;
    info.check_params = &FakeCheck;
    info.component_interface = component_interface;
    info.version = version;
    entries_.emplace_back();
    runtime::StageEntry& e = entries_.back();
    e.id = id;
    e.version = version ? version : "1.0.0";
    e.own_version = version != nullptr;
    e.info = &info;
    e.plugin = &plugin_;
    e.params = std::move(params);
    e.inputs = std::move(inputs);
    e.outputs = std::move(outputs);
    lookup_[id] = &e;
  }

  LfPluginInfo plugin_info_{};
  runtime::LoadedPlugin plugin_;
  std::deque<LfStageInfo> infos_;
  std::deque<runtime::StageEntry> entries_;
  StageLookup lookup_;
};

}  // namespace locforge::host::testing

#endif  // LOCFORGE_HOST_TEST_STAGES_H_

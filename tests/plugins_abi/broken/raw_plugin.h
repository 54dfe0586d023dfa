// A minimal valid plugin written against the raw C ABI (no adapter), which
// each broken case then spoils in exactly one way.
#ifndef LOCFORGE_TESTS_PLUGINS_ABI_BROKEN_RAW_PLUGIN_H_
#define LOCFORGE_TESTS_PLUGINS_ABI_BROKEN_RAW_PLUGIN_H_

#include "locforge/abi.h"

namespace raw {

inline int32_t CheckOk(const LfParam*, uint32_t, LfError*) { return LF_OK; }
inline void* Create(const LfParam*, uint32_t, LfError*) {
  static int instance;
  return &instance;
}
inline void Destroy(void*) {}
inline int32_t Run(void*, const LfRunContext*, LfError*) { return LF_OK; }

inline LfParamSpec IntParam(const char* name, const char* default_value, const char* doc) {
  LfParamSpec p{};
  p.struct_size = sizeof(LfParamSpec);
  p.name = name;
  p.type = LF_PARAM_INT;
  p.default_value = default_value;
  p.doc = doc;
  p.has_min = 1;
  p.min_value = 0;
  p.has_max = 1;
  p.max_value = 10;
  return p;
}

inline const LfPortSpec* OutputPort() {
  static const LfPortSpec port = {sizeof(LfPortSpec), "out", "report", 0, "An output"};
  return &port;
}

inline LfStageInfo WholeStage(const char* name) {
  LfStageInfo s{};
  s.struct_size = sizeof(LfStageInfo);
  s.kind = "broken";
  s.name = name;
  s.doc = "A deliberately broken stage";
  s.outputs = OutputPort();
  s.num_outputs = 1;
  s.flags = LF_STAGE_RUNNABLE;
  s.check_params = &CheckOk;
  s.create = &Create;
  s.destroy = &Destroy;
  s.run = &Run;
  return s;
}

inline LfPluginInfo Plugin(const LfStageInfo* stages, uint32_t n) {
  LfPluginInfo p{};
  p.abi_version = LF_ABI_VERSION;
  p.struct_size = sizeof(LfPluginInfo);
  p.name = "broken";
  p.version = "0.0.1";
  p.description = "Deliberately broken plugin";
  p.sdk_version = "0.1.0";
  p.stages = stages;
  p.num_stages = n;
  return p;
}

// A plugin of one whole stage with `params`: the body of the cases spoiled
// in a parameter. Internal linkage (static): the static locals of an extern
// inline function are one object per process, shared by every case loaded.
static inline const LfPluginInfo* OneStageWithParams(const char* name, const LfParamSpec* params, uint32_t n) {
  static const LfStageInfo stage = [&] {
    LfStageInfo s = WholeStage(name);
    s.params = params;
    s.num_params = n;
    return s;
  }();
  static const LfPluginInfo info = Plugin(&stage, 1);
  return &info;
}

}  // namespace raw

#endif  // LOCFORGE_TESTS_PLUGINS_ABI_BROKEN_RAW_PLUGIN_H_

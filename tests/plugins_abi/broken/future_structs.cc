// Not broken: a plugin built against a future minor ABI whose structs grew
// (fields appended). The host must step through its arrays by the plugin's
// struct_size and load it.
#include "raw_plugin.h"

namespace {
struct FutureParam {
  LfParamSpec base;
  const char* future_field;
};
struct FutureStage {
  LfStageInfo base;
  uint64_t future_fields[3];
};
struct FuturePlugin {
  LfPluginInfo base;
  uint64_t future_field;
};

FutureParam params[2] = {
    {raw::IntParam("alpha", "1", "First"), "x"},
    {raw::IntParam("beta", "2", "Second"), "y"}};

FutureStage MakeStage(const char* name) {
  FutureStage s{raw::WholeStage(name), {7, 8, 9}};
  s.base.struct_size = sizeof(FutureStage);
  s.base.params = &params[0].base;
  s.base.num_params = 2;
  return s;
}
}  // namespace

extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  static FutureStage stages[2] = {MakeStage("future_one"), MakeStage("future_two")};
  static FuturePlugin info = [] {
    for (auto& p : params) p.base.struct_size = sizeof(FutureParam);
    FuturePlugin p{raw::Plugin(&stages[0].base, 2), 42};
    p.base.struct_size = sizeof(FuturePlugin);
    return p;
  }();
  return &info.base;
}

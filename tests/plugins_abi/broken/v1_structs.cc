// Not broken: a plugin built before LfStageInfo::version and
// LfParamSpec::component_interface were appended. Its struct_size stops
// before them, so the host must not read them (they hold garbage here) and
// must key the stage's results by the plugin's version.
#include <cstddef>

#include "raw_plugin.h"

namespace {
const char* const kGarbage = reinterpret_cast<const char*>(0x1);

LfParamSpec MakeParam() {
  LfParamSpec p = raw::IntParam("alpha", "1", "First");
  p.struct_size = offsetof(LfParamSpec, component_interface);
  p.component_interface = kGarbage;
  return p;
}
LfParamSpec params[1] = {MakeParam()};

LfStageInfo MakeStage() {
  LfStageInfo s = raw::WholeStage("v1_stage");
  s.struct_size = offsetof(LfStageInfo, version);
  s.version = kGarbage;
  s.params = params;
  s.num_params = 1;
  return s;
}
LfStageInfo stages[1] = {MakeStage()};
}  // namespace

extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  static LfPluginInfo info = raw::Plugin(stages, 1);
  return &info;
}

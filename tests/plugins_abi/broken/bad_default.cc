// A parameter whose default breaks its own range [0, 10].
#include "raw_plugin.h"
static LfParamSpec params[] = {raw::IntParam("iterations", "42", "Iterations")};
static LfStageInfo stages[] = {[] {
  LfStageInfo s = raw::WholeStage("bad_default");
  s.params = params;
  s.num_params = 1;
  return s;
}()};
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  static LfPluginInfo info = raw::Plugin(stages, 1);
  return &info;
}

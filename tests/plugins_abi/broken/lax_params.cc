// Loads, but its check_params accepts anything and a parameter has no doc:
// the test kit must report both.
#include "raw_plugin.h"
static LfParamSpec params[] = {raw::IntParam("iterations", "3", "")};
static LfStageInfo stages[] = {[] {
  LfStageInfo s = raw::WholeStage("lax_params");
  s.params = params;
  s.num_params = 1;
  return s;
}()};
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  static LfPluginInfo info = raw::Plugin(stages, 1);
  return &info;
}

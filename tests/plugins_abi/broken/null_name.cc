// A stage with a NULL name.
#include "raw_plugin.h"
static LfStageInfo stages[] = {[] {
  LfStageInfo s = raw::WholeStage("placeholder");
  s.name = nullptr;
  return s;
}()};
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  static LfPluginInfo info = raw::Plugin(stages, 1);
  return &info;
}

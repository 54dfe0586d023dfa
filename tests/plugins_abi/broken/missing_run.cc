// A runnable whole stage without a run function.
#include "raw_plugin.h"
static LfStageInfo stages[] = {[] {
  LfStageInfo s = raw::WholeStage("missing_run");
  s.run = nullptr;
  return s;
}()};
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  static LfPluginInfo info = raw::Plugin(stages, 1);
  return &info;
}

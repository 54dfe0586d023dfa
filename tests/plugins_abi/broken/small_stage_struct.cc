// An LfStageInfo whose struct_size stops before the per-item functions.
#include "raw_plugin.h"
static LfStageInfo stages[] = {[] {
  LfStageInfo s = raw::WholeStage("small_stage_struct");
  s.struct_size = 24;
  return s;
}()};
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  static LfPluginInfo info = raw::Plugin(stages, 1);
  return &info;
}

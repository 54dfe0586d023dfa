// LfPluginInfo.struct_size smaller than version 1's struct.
#include "raw_plugin.h"
static LfStageInfo stages[] = {raw::WholeStage("small_struct")};
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  static LfPluginInfo info = [] {
    LfPluginInfo p = raw::Plugin(stages, 1);
    p.struct_size = 8;
    return p;
  }();
  return &info;
}

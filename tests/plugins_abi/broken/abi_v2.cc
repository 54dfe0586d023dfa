// Built for a future ABI: declares version 2 (and ignores the host's version).
#include "raw_plugin.h"
static LfStageInfo stages[] = {raw::WholeStage("abi_v2")};
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  static LfPluginInfo info = [] {
    LfPluginInfo p = raw::Plugin(stages, 1);
    p.abi_version = 2;
    return p;
  }();
  return &info;
}

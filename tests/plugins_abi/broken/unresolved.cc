// References a function no library defines: dlopen(RTLD_NOW) must refuse it.
#include "raw_plugin.h"
extern "C" int lftest_missing_function(void);
static LfStageInfo stages[] = {raw::WholeStage("unresolved")};
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  static LfPluginInfo info = raw::Plugin(stages, 1);
  if (lftest_missing_function() != 0) return nullptr;
  return &info;
}

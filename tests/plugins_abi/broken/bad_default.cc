// A parameter whose default breaks its own range [0, 10].
#include "raw_plugin.h"
static LfParamSpec params[] = {raw::IntParam("iterations", "42", "Iterations")};
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  return raw::OneStageWithParams("bad_default", params, 1);
}

// Loads, but its check_params accepts anything and a parameter has no doc:
// the test kit must report both.
#include "raw_plugin.h"
static LfParamSpec params[] = {raw::IntParam("iterations", "3", "")};
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  return raw::OneStageWithParams("lax_params", params, 1);
}

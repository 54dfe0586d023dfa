// A derived parameter (LF_PARAM_DERIVED: the stage derives its value when
// none is given) that declares a default of its own.
#include "raw_plugin.h"
static LfParamSpec params[] = {[] {
  LfParamSpec p = raw::IntParam("iterations", "5", "Iterations (default: the preset's)");
  p.flags = LF_PARAM_DERIVED;
  return p;
}()};
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  return raw::OneStageWithParams("derived_default", params, 1);
}

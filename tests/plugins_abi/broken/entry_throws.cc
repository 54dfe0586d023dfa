// An entry point that lets a C++ exception escape.
#include <stdexcept>
#include "raw_plugin.h"
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  throw std::runtime_error("static metadata failed to build");
}

// An entry point that serves no ABI version the host has.
#include "raw_plugin.h"
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) { return nullptr; }

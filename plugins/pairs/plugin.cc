// The stages of kind pairs: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("pairs", "1.0.0", "Image pair selection: retrieval, exhaustive, pose proximity, pairs file")

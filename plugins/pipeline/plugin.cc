// The stages of kind pipeline: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("pipeline", "1.0.0", "Whole baselines in one stage: COLMAP vocabulary-tree localization")

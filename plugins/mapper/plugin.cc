// The stages of kind mapper: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("mapper", "1.0.0", "Maps of posed images: COLMAP point_triangulator")

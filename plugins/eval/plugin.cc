// The stages of kind eval: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("eval", "1.0.0", "Evaluation: localization, tables, trajectories (ATE/RPE), joins of multi-sequence maps, calibration, depth maps")

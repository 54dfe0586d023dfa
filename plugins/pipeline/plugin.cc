// The stages of kind pipeline; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::colmap_stages {
LOCFORGE_DECLARE_STAGE(AddVocabTree);
}  // namespace locforge::colmap_stages

LOCFORGE_PLUGIN("pipeline", "1.0.0", "Whole baselines in one stage: COLMAP vocabulary-tree localization",
                locforge::Exported<locforge::colmap_stages::AddVocabTree>)

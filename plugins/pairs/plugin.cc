// The stages of kind pairs; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::retrieval {
LOCFORGE_DECLARE_STAGE(AddRetrieval);
LOCFORGE_DECLARE_STAGE(AddExhaustive);
LOCFORGE_DECLARE_STAGE(AddPoseProximity);
LOCFORGE_DECLARE_STAGE(AddPairsFile);
}  // namespace locforge::retrieval

LOCFORGE_PLUGIN("pairs", "1.0.0", "Image pair selection: retrieval, exhaustive, pose proximity, pairs file",
                locforge::Exported<locforge::retrieval::AddRetrieval>,
                locforge::Exported<locforge::retrieval::AddExhaustive>,
                locforge::Exported<locforge::retrieval::AddPoseProximity>,
                locforge::Exported<locforge::retrieval::AddPairsFile>)

// The stages of kind verify; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::matching {
LOCFORGE_DECLARE_STAGE(AddTwoView);
LOCFORGE_DECLARE_STAGE(AddKnownPoseEpipolar);
}  // namespace locforge::matching

LOCFORGE_PLUGIN("verify", "1.0.0", "Geometric verification of matches",
                locforge::Exported<locforge::matching::AddTwoView>,
                locforge::Exported<locforge::matching::AddKnownPoseEpipolar>)

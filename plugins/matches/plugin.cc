// The stages of kind matches; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::matching {
LOCFORGE_DECLARE_STAGE(AddMutualNn);
}  // namespace locforge::matching

LOCFORGE_PLUGIN("matches", "1.0.0", "Descriptor matching",
                locforge::Exported<locforge::matching::AddMutualNn>)

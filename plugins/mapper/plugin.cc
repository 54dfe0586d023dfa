// The stages of kind mapper; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::colmap_stages {
LOCFORGE_DECLARE_STAGE(AddColmapTriangulator);
}  // namespace locforge::colmap_stages

LOCFORGE_PLUGIN("mapper", "1.0.0", "Maps of posed images: COLMAP point_triangulator",
                locforge::Exported<locforge::colmap_stages::AddColmapTriangulator>)

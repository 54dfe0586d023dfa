// The stages of kind localizer; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::localization {
LOCFORGE_DECLARE_STAGE(AddPnP);
}  // namespace locforge::localization

namespace locforge::colmap_stages {
LOCFORGE_DECLARE_STAGE(AddColmapRegistrator);
}  // namespace locforge::colmap_stages

LOCFORGE_PLUGIN("localizer", "1.0.0", "Structure-based localization: in-process PnP, COLMAP image_registrator",
                locforge::Exported<locforge::localization::AddPnP>,
                locforge::Exported<locforge::colmap_stages::AddColmapRegistrator>)

// The stages of kind localizer; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::localization {
LOCFORGE_DECLARE_STAGE(AddPnP);
}  // namespace locforge::localization

namespace locforge::regression {
LOCFORGE_DECLARE_STAGE(AddPoseNet);
LOCFORGE_DECLARE_STAGE(AddEsac);
}  // namespace locforge::regression

namespace locforge::colmap_stages {
LOCFORGE_DECLARE_STAGE(AddColmapRegistrator);
}  // namespace locforge::colmap_stages

LOCFORGE_PLUGIN("localizer", "1.1.0",
                "Localization: structure-based (in-process PnP, COLMAP image_registrator), absolute pose "
                "regression (PoseNet) and scene-coordinate regression with experts (ESAC) on ONNX networks",
                locforge::Exported<locforge::localization::AddPnP>,
                locforge::Exported<locforge::colmap_stages::AddColmapRegistrator>,
                locforge::Exported<locforge::regression::AddPoseNet>,
                locforge::Exported<locforge::regression::AddEsac>)

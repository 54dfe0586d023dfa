// The stages of kind localizer: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("localizer", "1.1.0",
                "Localization: structure-based (in-process PnP, COLMAP image_registrator), absolute pose "
                "regression (PoseNet) and scene-coordinate regression with experts (ESAC) on ONNX networks")

// Learned regression localizers: absolute pose regression and scene-coordinate
// regression with experts; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::regression {
LOCFORGE_DECLARE_STAGE(AddPoseNet);
LOCFORGE_DECLARE_STAGE(AddEsac);
}  // namespace locforge::regression

LOCFORGE_PLUGIN("regression", "1.0.0",
                "Regression localizers on ONNX networks (OpenCV dnn): PoseNet, ESAC",
                locforge::Exported<locforge::regression::AddPoseNet>,
                locforge::Exported<locforge::regression::AddEsac>)

// The stages of kind eval; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::evaluation {
LOCFORGE_DECLARE_STAGE(AddLocalizationEval);
LOCFORGE_DECLARE_STAGE(AddTable);
}  // namespace locforge::evaluation

namespace locforge::eval {
LOCFORGE_DECLARE_STAGE(AddTrajectoryEval);
LOCFORGE_DECLARE_STAGE(AddJoinsEval);
LOCFORGE_DECLARE_STAGE(AddDepthEval);
}  // namespace locforge::eval

namespace locforge::sfm_gt {
LOCFORGE_DECLARE_STAGE(AddCalibrationEval);
}  // namespace locforge::sfm_gt

LOCFORGE_PLUGIN("eval", "1.0.0", "Evaluation: localization, tables, trajectories (ATE/RPE), joins of multi-sequence maps, calibration, depth maps",
                locforge::Exported<locforge::evaluation::AddLocalizationEval>,
                locforge::Exported<locforge::evaluation::AddTable>,
                locforge::Exported<locforge::eval::AddTrajectoryEval>,
                locforge::Exported<locforge::eval::AddJoinsEval>,
                locforge::Exported<locforge::eval::AddDepthEval>,
                locforge::Exported<locforge::sfm_gt::AddCalibrationEval>)

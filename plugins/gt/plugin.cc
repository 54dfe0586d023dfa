#include "stages.h"

#ifdef LOCFORGE_SFM_GT_HAVE_BA
LOCFORGE_PLUGIN("sfm_gt", "1.0.0",
                "SfM half of the ground truth: calibration perturbation, camera dataset, "
                "spline bundle adjustment outer loop, calibration evaluation",
                locforge::sfm_gt::PerturbStage, locforge::sfm_gt::ImagesStage,
                locforge::sfm_gt::SplineBAStage, locforge::sfm_gt::CalibrationEvalStage)
#else
LOCFORGE_PLUGIN("sfm_gt", "1.0.0",
                "SfM half of the ground truth (built without the spline bundle adjuster)",
                locforge::sfm_gt::PerturbStage, locforge::sfm_gt::ImagesStage,
                locforge::sfm_gt::CalibrationEvalStage)
#endif

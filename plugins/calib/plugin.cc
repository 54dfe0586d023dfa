// The stages of kind calib: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("calib", "0.6.0", "Calibration: LiDAR-LiDAR extrinsic, perturbed calibrations")

// The stages of kind features: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("features", "1.0.0", "Local features: OpenCV SIFT, R2D2, D2-Net, XFeat and ALIKE (ONNX), import of kapture features")

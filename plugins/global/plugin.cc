// The stages of kind global: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("global", "1.0.0", "Global image descriptors: DenseVLAD, NetVLAD, AP-GeM, DELG (ONNX), import")

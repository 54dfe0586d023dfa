// The stages of kind analysis: what explains a method's failures.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("analysis", "1.0.0", "Analyses of localization results by image content: low-frequency score, crowdedness (truth, person segmentation or person detection), the paper's Tables 5 and 6, recall vs crowd density")

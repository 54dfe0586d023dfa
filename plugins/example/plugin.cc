#include "stages.h"

LOCFORGE_PLUGIN("examples", "1.0.0",
                "Example stages: synthetic images, image folder import, image statistics",
                locforge::examples::SyntheticImages, locforge::examples::ImageList,
                locforge::examples::ImageStats)

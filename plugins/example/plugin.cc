// The examples plugin: the SDK's example stages in one plugin, a whole small
// example of one (example/image_stats here, the sources
// ../source/synthetic_images.cc and ../source/image_list.cc), each registering
// itself in its own file (LOCFORGE_REGISTER_STAGE).
#include "locforge/plugin.h"

// 1.1.0: a damaged image fails (image_list, image_stats).
LOCFORGE_PLUGIN("examples", "1.1.0", "Example stages: synthetic images, image folder import, image statistics")

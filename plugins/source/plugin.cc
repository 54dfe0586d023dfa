// The stages of kind source: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
// source/simulator is its own plugin (simulator/),
// the example sources source/synthetic_images and source/image_list are in
// the examples plugin (../example/plugin.cc).
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("source", "0.7.0", "Sources: kapture folders, LiDAR keyframes, Velodyne packet captures")

// The simulator plugin: the stage source/simulator (../simulator.cc) over the
// simulator's library (this folder), a plugin of its own so that users of
// real data do not load it.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("simulator", "0.2.0", "Synthetic crowded indoor recordings with ground truth")

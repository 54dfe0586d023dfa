// The stages of kind registration: each registers itself in its own file (LOCFORGE_REGISTER_STAGE), listed in
// the plugin's SOURCES; each stage's version keys its cached results.
#include "locforge/plugin.h"

LOCFORGE_PLUGIN("registration", "1.0.0", "Point-cloud registration back-ends (components): GICP, PCL GICP, PCL point-to-plane ICP")

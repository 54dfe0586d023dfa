// The stages of kind registration; each stage's version keys its cached results.
#include "locforge/plugin.h"

namespace locforge::gicp {
LOCFORGE_DECLARE_STAGE(AddGicp);
}  // namespace locforge::gicp

namespace locforge::pclreg {
LOCFORGE_DECLARE_STAGE(AddPclGicp);
LOCFORGE_DECLARE_STAGE(AddIcpPlane);
}  // namespace locforge::pclreg

LOCFORGE_PLUGIN("registration", "1.0.0", "Point-cloud registration back-ends (components): GICP, PCL GICP, PCL point-to-plane ICP",
                locforge::Exported<locforge::gicp::AddGicp>,
                locforge::Exported<locforge::pclreg::AddPclGicp>,
                locforge::Exported<locforge::pclreg::AddIcpPlane>)

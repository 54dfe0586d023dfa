// global/apgem (learned_stage.h).
#include "learned_stage.h"

namespace locforge::learned {

LOCFORGE_REGISTER_STAGE(GlobalStage<GlobalModel::kApGem>)

}  // namespace locforge::learned

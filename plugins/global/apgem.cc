// global/apgem (learned_stage.h).
#include "learned_stage.h"

namespace locforge::learned {

LOCFORGE_EXPORT_STAGE(AddApGem, GlobalStage<GlobalModel::kApGem>)

}  // namespace locforge::learned

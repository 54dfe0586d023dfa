// global/delg (learned_stage.h).
#include "learned_stage.h"

namespace locforge::learned {

LOCFORGE_EXPORT_STAGE(AddDelg, GlobalStage<GlobalModel::kDelg>)

}  // namespace locforge::learned

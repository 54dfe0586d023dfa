// global/netvlad (learned_stage.h).
#include "learned_stage.h"

namespace locforge::learned {

LOCFORGE_EXPORT_STAGE(AddNetVlad, GlobalStage<GlobalModel::kNetVlad>)

}  // namespace locforge::learned

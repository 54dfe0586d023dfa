// global/netvlad (learned_stage.h).
#include "learned_stage.h"

namespace locforge::global {

using namespace ::locforge::learned;  // the library this stage wires

LOCFORGE_REGISTER_STAGE(GlobalStage<GlobalModel::kNetVlad>)

}  // namespace locforge::global

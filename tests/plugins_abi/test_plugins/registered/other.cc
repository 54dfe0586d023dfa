// A second plugin of registered stages, loaded beside lftest_registered: each
// plugin lists only the stages its own files registered.
#include "locforge/plugin.h"

namespace {

struct NoOptions {
  static void Declare(locforge::ParamSchema<NoOptions>&) {}
};

class RegisteredC : public locforge::Stage<NoOptions> {
 public:
  static locforge::StageMeta Meta() {
    return {"test", "registered_c", "Registered in another plugin", {}, {{"out", "report", "nothing"}}};
  }
  using Stage::Stage;
  void Run(locforge::RunContext&) override {}
};

}  // namespace

LOCFORGE_REGISTER_STAGE(RegisteredC)

LOCFORGE_PLUGIN("lftest_registered_other", "1.0.0", "A registered stage in a second plugin")

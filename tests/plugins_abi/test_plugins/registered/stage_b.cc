// The second file of lftest_registered: a registered stage and the plugin's
// entry point, which names none of its stages.
#include "locforge/plugin.h"

namespace {

struct NoOptions {
  static void Declare(locforge::ParamSchema<NoOptions>&) {}
};

class RegisteredB : public locforge::Stage<NoOptions> {
 public:
  static locforge::StageMeta Meta() {
    return {"test", "registered_b", "Registered in its own file", {}, {{"out", "report", "nothing"}}};
  }
  using Stage::Stage;
  void Run(locforge::RunContext&) override {}
};

}  // namespace

LOCFORGE_REGISTER_STAGE(RegisteredB)

LOCFORGE_PLUGIN("lftest_registered", "1.0.0", "Stages registered in their own files")

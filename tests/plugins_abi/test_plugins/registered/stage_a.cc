// A stage that registers itself where it is defined (LOCFORGE_REGISTER_STAGE):
// one of two files of the plugin lftest_registered.
#include "locforge/plugin.h"

namespace {

struct NoOptions {
  static void Declare(locforge::ParamSchema<NoOptions>&) {}
};

class RegisteredA : public locforge::Stage<NoOptions> {
 public:
  static locforge::StageMeta Meta() {
    return {"test", "registered_a", "Registered in its own file", {}, {{"out", "report", "nothing"}}};
  }
  using Stage::Stage;
  void Run(locforge::RunContext&) override {}
};

}  // namespace

LOCFORGE_REGISTER_STAGE(RegisteredA)

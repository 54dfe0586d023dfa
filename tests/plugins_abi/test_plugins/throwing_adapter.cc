// A stage whose constructor throws, through the adapter (which must turn it
// into a NULL instance and a message).
#include "locforge/plugin.h"

namespace {

class ThrowingCreate : public locforge::Stage<locforge::NoOptions> {
 public:
  static locforge::StageMeta Meta() {
    return {"test", "throwing_create", "Its constructor throws", {},
            {{"out", "report", "Never written"}}};
  }
  explicit ThrowingCreate(locforge::NoOptions o) : Stage(o) {
    throw locforge::Error("constructor refused to build");
  }
  void Run(locforge::RunContext&) override {}
};

}  // namespace

LOCFORGE_PLUGIN("lftest_throwing_adapter", "1.0.0", "Throwing constructor", ThrowingCreate)

// Loads fine, but bypasses the adapter and lets C++ exceptions escape from
// check_params (stage throwing_check), create (throwing_create) and run
// (throwing_run). The host must turn each into an error, not a crash.
#include <stdexcept>
#include "raw_plugin.h"

static int32_t CheckThrows(const LfParam*, uint32_t, LfError*) {
  throw std::runtime_error("check_params exploded");
}
static void* CreateThrows(const LfParam*, uint32_t, LfError*) {
  throw std::runtime_error("factory exploded");
}
static int32_t RunThrows(void*, const LfRunContext*, LfError*) {
  throw std::logic_error("run exploded");
}

static LfStageInfo stages[] = {
    [] {
      LfStageInfo s = raw::WholeStage("throwing_check");
      s.check_params = &CheckThrows;
      return s;
    }(),
    [] {
      LfStageInfo s = raw::WholeStage("throwing_create");
      s.create = &CreateThrows;
      return s;
    }(),
    [] {
      LfStageInfo s = raw::WholeStage("throwing_run");
      s.run = &RunThrows;
      return s;
    }()};
extern "C" LF_EXPORT const LfPluginInfo* locforge_plugin_entry(uint32_t) {
  static LfPluginInfo info = raw::Plugin(stages, 3);
  return &info;
}

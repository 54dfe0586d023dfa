#include "lidar_params.h"

namespace locforge::lidar {

fs::path RecordingOf(RunContext& ctx, const std::string& dataset_param, const std::string& stage) {
  if (ctx.HasInput("recording")) {
    if (!dataset_param.empty())
      throw ParamError(stage + ": the recording is given twice: as the dataset parameter (" + dataset_param +
                       ") and as the recording input; keep one");
    return ctx.Input("recording");
  }
  if (dataset_param.empty())
    throw ParamError(stage + ": no recording: set the dataset parameter (in the shipped graphs: --set dataset=DIR, "
                     "a kapture recording folder) or wire the recording input");
  return dataset_param;
}

}  // namespace locforge::lidar

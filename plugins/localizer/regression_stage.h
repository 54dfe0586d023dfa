// The base of localizer/posenet and localizer/esac: one item per image of the
// `query` input's records_camera.txt, its result written by
// ../localizer/pnp/query_results (trajectories, failures.txt,
// localization_stats.csv as localizer/pnp writes them).
#ifndef LOCFORGE_PLUGINS_LOCALIZER_REGRESSION_STAGE_H_
#define LOCFORGE_PLUGINS_LOCALIZER_REGRESSION_STAGE_H_

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "onnx_net.h"
#include "query_results.h"

namespace locforge::regression {

inline const PortMeta kQueryPort{"query", "kapture.dataset", "query sensors and records_camera (images)"};
inline const PortMeta kTrajectoriesPort{
    "trajectories", "kapture.trajectories", "estimated query poses (+ failures.txt, localization_stats.csv)"};

template <typename Options>
class RegressionStage : public PerItemStage<Options> {
 public:
  using PerItemStage<Options>::PerItemStage;

  std::vector<std::string> ListItems(RunContext& ctx) override {
    Load(ctx);
    std::vector<std::string> out;
    for (const auto& [image, record] : queries_) out.push_back(image);
    return out;
  }

  void Finalize(RunContext& ctx) override {
    Load(ctx);
    std::vector<localization::QueryItemInfo> items;
    for (const auto& [image, record] : queries_) items.push_back({image, record.timestamp, record.device_id});
    const int ok = localization::WriteLocalizationOutputs(ctx.output_dir(), items, StatNames(),
                                                          query_->sensors(), kapture::Rigs());
    ctx.Info("localized " + std::to_string(ok) + " of " + std::to_string(items.size()) + " queries");
  }

 protected:
  virtual std::vector<std::string> StatNames() const = 0;

  // The query image `image` as 8-bit RGB and its camera.
  cv::Mat QueryImage(RunContext& ctx, const std::string& image, Camera* camera) {
    Load(ctx);
    const kapture::DataRecord& record = queries_.at(image);
    const kapture::Sensor* sensor = query_->sensors().Find(record.device_id);
    if (!sensor || !sensor->camera)
      throw InputError(kapture::layout::kSensors, 0, record.device_id, "query camera not found");
    *camera = *sensor->camera;
    return learned::ReadRgb(ctx.Input("query"), image);
  }

 private:
  void Load(RunContext& ctx) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (query_) return;
    auto query = std::make_unique<kapture::Kapture>(ctx.Input("query"));
    for (const auto& r : query->ReadDataRecords(kapture::kSensorCamera)) queries_[r.path] = r;
    query_ = std::move(query);
  }

  std::mutex mutex_;
  std::unique_ptr<kapture::Kapture> query_;
  std::map<std::string, kapture::DataRecord> queries_;
};

}  // namespace locforge::regression

#endif  // LOCFORGE_PLUGINS_LOCALIZER_REGRESSION_STAGE_H_

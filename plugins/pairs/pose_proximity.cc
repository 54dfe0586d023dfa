// pairs/pose_proximity: pairs of images whose known poses are close.
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <unordered_map>

#include "global_features.h"
#include "locforge/units.h"
#include "locforge/kapture/csv.h"
#include "locforge/kapture/kapture.h"
#include "locforge/plugin.h"
#include "pairs_io.h"

namespace locforge::pairs {

using namespace ::locforge::retrieval;  // the library this stage wires

namespace {

namespace k = locforge::kapture;

struct ProximityOptions {
  double max_distance_m = 5.0;
  double max_angle_deg = 60.0;
  int topk = 0;
  int topk_revisit = 0;
  double revisit_min_dt_s = 10.0;
  double seconds_per_unit = kDefaultSecondsPerUnit;
  static void Declare(ParamSchema<ProximityOptions>& s) {
    s.Add("max_distance_m", &ProximityOptions::max_distance_m, "max distance of camera centres (m)")
        .Min(0);
    s.Add("max_angle_deg", &ProximityOptions::max_angle_deg,
          "max angle between the optical axes (degrees)").Range(0, 180);
    s.Add("topk", &ProximityOptions::topk, "closest map images kept per image (0: all)").Min(0);
    s.Add("topk_revisit", &ProximityOptions::topk_revisit,
          "with topk: keep further neighbours until at least this many of an image's pairs are "
          "revisits (images taken >= revisit_min_dt_s apart: other sequences, loops), which the "
          "topk closest (mostly images of the same moment) may not contain")
        .Min(0);
    s.Add("revisit_min_dt_s", &ProximityOptions::revisit_min_dt_s,
          "time between two images of a revisit pair (s)").Min(0);
    AddSecondsPerUnit(s, &ProximityOptions::seconds_per_unit);
  }
};

class PoseProximityStage : public Stage<ProximityOptions> {
 public:
  static StageMeta Meta() {
    StageMeta meta = {"pairs", "pose_proximity",
            "Pairs of images whose known poses are close (centre distance and viewing angle)",
            {{"map", "kapture.dataset", "map images with poses"},
             {"query", "kapture.dataset", "query images with poses (query-to-map mode)", LF_PORT_OPTIONAL}},
            {{"pairs", "kapture.pairs", "pairs.txt; score = 1 / (1 + distance in m)"}}};
    meta.version = "1.0.0";
    return meta;
  }
  using Stage::Stage;

  struct View {
    std::string image;
    Eigen::Vector3d centre, axis;
    double time_s = 0;
  };

  static std::vector<View> Views(const fs::path& dataset, double seconds_per_unit, RunContext& ctx) {
    k::Kapture kap(dataset);
    std::map<std::string, View> views;
    int64_t without_pose = 0;
    kap.ForEachDataRecord("camera", [&](const k::DataRecord& r) {
      const auto pose = kap.DevicePose(r.timestamp, r.device_id);
      if (!pose) return void(++without_pose);
      views[r.path] = {r.path, pose->Center(), pose->R().transpose() * Eigen::Vector3d::UnitZ(),
                       static_cast<double>(r.timestamp) * seconds_per_unit};
    });
    if (without_pose) ctx.Warn(std::to_string(without_pose) + " images without a pose in " + dataset.string());
    std::vector<View> out;
    for (auto& [name, v] : views) out.push_back(v);
    return out;
  }

  void Run(RunContext& ctx) override {
    const auto& o = options();
    const auto map = Views(ctx.Input("map"), o.seconds_per_unit, ctx);
    const bool query_mode = ctx.HasInput("query");
    const auto queries = query_mode ? Views(ctx.Input("query"), o.seconds_per_unit, ctx) : map;
    // Voxel hash of map centres, cell = max distance.
    const double cell = std::max(o.max_distance_m, 1e-3);
    auto key = [&](const Eigen::Vector3d& c) {
      return std::array<int64_t, 3>{int64_t(std::floor(c.x() / cell)), int64_t(std::floor(c.y() / cell)),
                                    int64_t(std::floor(c.z() / cell))};
    };
    std::map<std::array<int64_t, 3>, std::vector<int>> grid;
    for (int i = 0; i < static_cast<int>(map.size()); ++i) grid[key(map[i].centre)].push_back(i);
    const double cos_max = std::cos(o.max_angle_deg * M_PI / 180.0);
    std::vector<ScoredPair> pairs;
    std::set<std::pair<std::string, std::string>> seen;  // map-to-map: each unordered pair once
    for (const auto& q : queries) {
      // Every neighbour, whatever the name order: the top-k of an image must
      // not depend on how its neighbours' names sort.
      std::vector<std::pair<double, int>> near;
      const auto c = key(q.centre);
      for (int64_t dx = -1; dx <= 1; ++dx)
        for (int64_t dy = -1; dy <= 1; ++dy)
          for (int64_t dz = -1; dz <= 1; ++dz) {
            auto it = grid.find({c[0] + dx, c[1] + dy, c[2] + dz});
            if (it == grid.end()) continue;
            for (int m : it->second) {
              if (map[m].image == q.image) continue;
              const double d = (map[m].centre - q.centre).norm();
              if (d <= o.max_distance_m && map[m].axis.dot(q.axis) >= cos_max - 1e-12) near.emplace_back(d, m);
            }
          }
      std::sort(near.begin(), near.end());
      // The topk closest, plus the topk_revisit closest revisits not among them.
      std::vector<std::pair<double, int>> kept;
      int revisits = 0;
      for (size_t i = 0; i < near.size(); ++i) {
        const bool revisit = std::abs(map[near[i].second].time_s - q.time_s) >= o.revisit_min_dt_s;
        if (o.topk == 0 || static_cast<int>(i) < o.topk) {
          kept.push_back(near[i]);
        } else if (revisit && revisits < o.topk_revisit) {
          kept.push_back(near[i]);
        } else {
          continue;
        }
        revisits += revisit;
      }
      for (const auto& [d, m] : kept) {
        if (!query_mode) {
          const auto& a = std::min(q.image, map[m].image);
          const auto& b = std::max(q.image, map[m].image);
          if (!seen.insert({a, b}).second) continue;
        }
        pairs.push_back({q.image, map[m].image, 1.0 / (1.0 + d)});
      }
    }
    WritePairs(ctx.output_dir(), pairs);
  }
};

}  // namespace

LOCFORGE_REGISTER_STAGE(PoseProximityStage)

}  // namespace locforge::pairs

#include "plot.h"

#include <map>

namespace locforge::lidar {

plot::Figure TopDownFigure(const std::vector<PlotSequence>& before, const std::vector<PlotSequence>& after,
                           const std::vector<std::pair<int, int>>& loops) {
  plot::Figure f;
  f.title = "Trajectories: before (dashed) / after (solid) optimisation, loop edges in red";
  f.x_label = "x (m)";
  f.y_label = "y (m)";
  f.equal_aspect = true;
  f.width = 1000;
  f.height = 800;
  std::map<int, Eigen::Vector2d> at;
  for (size_t s = 0; s < after.size(); ++s) {
    const std::string color = plot::PaletteColor(s);
    if (s < before.size()) {
      plot::Series b{before[s].name + " before", {}, {}, color, false, true};
      for (const auto& p : before[s].xy) {
        b.x.push_back(p.x());
        b.y.push_back(p.y());
      }
      f.series.push_back(b);
    }
    plot::Series a{after[s].name, {}, {}, color, false, false};
    for (size_t i = 0; i < after[s].xy.size(); ++i) {
      a.x.push_back(after[s].xy[i].x());
      a.y.push_back(after[s].xy[i].y());
      at[after[s].ids[i]] = after[s].xy[i];
    }
    f.series.push_back(a);
  }
  for (const auto& [from, to] : loops) {
    if (!at.count(from) || !at.count(to)) continue;
    f.segments.push_back({at[from].x(), at[from].y(), at[to].x(), at[to].y(), "#d62728"});
  }
  return f;
}

void WriteTopDown(const fs::path& stem, const std::vector<PlotSequence>& before,
                  const std::vector<PlotSequence>& after, const std::vector<std::pair<int, int>>& loops) {
  const plot::Figure f = TopDownFigure(before, after, loops);
  plot::WriteFigure(f, stem.string() + ".svg");
  plot::WriteFigure(f, stem.string() + ".png");
}

}  // namespace locforge::lidar

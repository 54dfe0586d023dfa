#include "plot.h"

#include <map>

namespace locforge::lidar {

plot::Figure TopDownFigure(const std::vector<PlotSequence>& before, const std::vector<PlotSequence>& after,
                           const std::vector<std::pair<int, int>>& loops) {
  plot::Figure f;
  f.title = "Pose graph: trajectories before and after optimisation";
  f.x_label = "x (m)";
  f.y_label = "y (m)";
  f.equal_aspect = true;
  f.width = 900;
  f.height = 720;
  std::map<int, Eigen::Vector2d> at;
  // Drawn (and listed in the legend) in this order: the dashed "before"
  // lines under the solid results, then the style keys: one "before" entry
  // for every dashed line, one for the loop edges.
  std::vector<plot::Series> solid;
  for (size_t s = 0; s < after.size(); ++s) {
    const std::string color = plot::PaletteColor(s);
    if (s < before.size()) {
      // Lighter than the result it was optimised into.
      plot::Series b{"", {}, {}, color + "99", false, true};
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
    solid.push_back(a);
  }
  for (plot::Series& a : solid) f.series.push_back(std::move(a));
  if (!before.empty()) f.series.push_back({"before optimisation", {}, {}, "#808080", false, true});
  const std::string loop_color = "#00000059";  // grey where one edge, darker where many
  for (const auto& [from, to] : loops) {
    if (!at.count(from) || !at.count(to)) continue;
    f.segments.push_back({at[from].x(), at[from].y(), at[to].x(), at[to].y(), loop_color});
  }
  if (!f.segments.empty()) f.series.push_back({"loop closures", {}, {}, loop_color});
  return f;
}

void WriteTopDown(const fs::path& stem, const std::vector<PlotSequence>& before,
                  const std::vector<PlotSequence>& after, const std::vector<std::pair<int, int>>& loops) {
  const plot::Figure f = TopDownFigure(before, after, loops);
  plot::WriteFigure(f, stem.string() + ".svg");
  plot::WriteFigure(f, stem.string() + ".png");
}

}  // namespace locforge::lidar

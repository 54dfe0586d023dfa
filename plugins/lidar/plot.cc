#include "plot.h"

#include <algorithm>
#include <map>
#include <sstream>

namespace locforge::lidar {

namespace {
const char* kColors[] = {"#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#17becf", "#e377c2"};

void Panel(std::ostringstream& o, const std::vector<PlotSequence>& seqs,
           const std::vector<std::pair<int, int>>& loops, const std::string& title, double offset_x,
           const Eigen::Vector2d& lo, double scale, double height) {
  auto X = [&](const Eigen::Vector2d& p) { return offset_x + 20 + (p.x() - lo.x()) * scale; };
  auto Y = [&](const Eigen::Vector2d& p) { return height - 20 - (p.y() - lo.y()) * scale; };
  o << "<text x='" << offset_x + 20 << "' y='16' font-size='14'>" << title << "</text>\n";
  std::map<int, Eigen::Vector2d> at;
  for (size_t s = 0; s < seqs.size(); ++s) {
    o << "<polyline fill='none' stroke-width='1.5' stroke='" << kColors[s % 7] << "' points='";
    for (size_t i = 0; i < seqs[s].xy.size(); ++i) {
      o << X(seqs[s].xy[i]) << ',' << Y(seqs[s].xy[i]) << ' ';
      at[seqs[s].ids[i]] = seqs[s].xy[i];
    }
    o << "'><title>" << seqs[s].name << "</title></polyline>\n";
  }
  for (const auto& [a, b] : loops) {
    if (!at.count(a) || !at.count(b)) continue;
    o << "<line stroke='red' stroke-width='1' x1='" << X(at[a]) << "' y1='" << Y(at[a]) << "' x2='"
      << X(at[b]) << "' y2='" << Y(at[b]) << "'/>\n";
  }
}
}  // namespace

std::string TopDownSvg(const std::vector<PlotSequence>& before, const std::vector<PlotSequence>& after,
                       const std::vector<std::pair<int, int>>& loops) {
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (const auto* set : {&before, &after})
    for (const auto& s : *set)
      for (const auto& p : s.xy) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
  if (lo.x() > hi.x()) lo = hi = Eigen::Vector2d::Zero();
  const double panel = 500;
  const double scale = (panel - 40) / std::max(1e-3, (hi - lo).maxCoeff());
  const double height = (hi.y() - lo.y()) * scale + 40;
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << 2 * panel << "' height='" << height << "'>\n"
    << "<rect width='100%' height='100%' fill='white'/>\n";
  Panel(o, before, loops, "before optimisation", 0, lo, scale, height);
  Panel(o, after, loops, "after optimisation", panel, lo, scale, height);
  o << "</svg>\n";
  return o.str();
}

}  // namespace locforge::lidar

#include "crowd_sweep.h"

#include <map>

#include "locforge/error.h"
#include "locforge/params.h"

namespace locforge::analysis {

using evaluation::QueryError;
using evaluation::Table;
using evaluation::Threshold;

void CheckSweep(const std::vector<SweepSet>& sets) {
  for (size_t s = 0; s < sets.size(); ++s) {
    const SweepSet& set = sets[s];
    if (set.methods.size() != sets.front().methods.size())
      throw InputError("crowd sweep: set " + std::to_string(s) + " has " + std::to_string(set.methods.size()) +
                       " methods, the first set " + std::to_string(sets.front().methods.size()));
    std::map<std::string, const ImageContent*> by_image;
    for (const auto& c : set.content) by_image[c.image] = &c;
    for (size_t m = 0; m < set.methods.size(); ++m) {
      if (set.methods[m].method != sets.front().methods[m].method)
        throw InputError("crowd sweep: set " + std::to_string(s) + " method " + std::to_string(m) + " is '" +
                         set.methods[m].method + "', the first set's '" + sets.front().methods[m].method + "'");
      for (const QueryError& e : set.methods[m].errors) {
        const auto it = by_image.find(e.image);
        if (it == by_image.end())
          throw InputError("crowd sweep: set " + std::to_string(s) + ", method '" + set.methods[m].method +
                           "': query " + e.image + " has no image-content row");
        if (it->second->crowdedness_percent < 0)
          throw InputError("crowd sweep: query " + e.image + " has no crowdedness (no person mask)");
      }
    }
  }
}

double MeanCrowdedness(const SweepSet& set) {
  double sum = 0;
  size_t n = 0;
  for (const auto& c : set.content)
    if (c.crowdedness_percent >= 0) sum += c.crowdedness_percent, ++n;
  return n ? sum / n : 0;
}

Table SweepTable(const std::vector<SweepSet>& sets, const std::vector<Threshold>& thresholds) {
  Table table;
  table.header = {"people / 100 m^2", "queries", "mean crowdedness (%)", "crowded queries (%)"};
  if (!sets.empty())
    for (const auto& m : sets.front().methods) table.header.push_back(m.method);
  for (const SweepSet& set : sets) {
    size_t crowded = 0;
    for (const auto& c : set.content) crowded += c.crowded;
    std::vector<std::string> row = {FormatDouble(set.setting), std::to_string(set.content.size()),
                                    evaluation::Percent(MeanCrowdedness(set) / 100),
                                    evaluation::Percent(set.content.empty() ? 0 : double(crowded) / set.content.size())};
    for (const auto& m : set.methods) row.push_back(RecallCell(m.errors, thresholds));
    table.rows.push_back(std::move(row));
  }
  return table;
}

Table BinnedTable(const std::vector<SweepSet>& sets, const std::vector<double>& edges, const std::vector<Threshold>& thresholds) {
  Table table;
  table.header = {"query crowdedness (%)", "queries"};
  if (sets.empty() || edges.empty()) return table;
  const size_t methods = sets.front().methods.size();
  for (const auto& m : sets.front().methods) table.header.push_back(m.method);
  const size_t bins = edges.size();
  std::vector<std::vector<std::vector<QueryError>>> binned(bins, std::vector<std::vector<QueryError>>(methods));
  for (const SweepSet& set : sets) {
    std::map<std::string, double> crowd;
    for (const auto& c : set.content) crowd[c.image] = c.crowdedness_percent;
    for (size_t m = 0; m < methods; ++m)
      for (const QueryError& e : set.methods[m].errors) {
        const double c = crowd.at(e.image);
        for (size_t b = bins; b-- > 0;)
          if (c >= edges[b]) {
            binned[b][m].push_back(e);
            break;
          }
      }
  }
  for (size_t b = 0; b < bins; ++b) {
    const std::string label = b + 1 < bins ? "[" + FormatDouble(edges[b]) + ", " + FormatDouble(edges[b + 1]) + ")"
                                           : ">= " + FormatDouble(edges[b]);
    std::vector<std::string> row = {label, std::to_string(binned[b].empty() ? 0 : binned[b][0].size())};
    for (size_t m = 0; m < methods; ++m) row.push_back(RecallCell(binned[b][m], thresholds));
    table.rows.push_back(std::move(row));
  }
  return table;
}

plot::Figure SweepFigure(const std::vector<SweepSet>& sets, const Threshold& threshold) {
  plot::Figure f;
  f.title = "Recall vs crowdedness (" + FormatDouble(threshold.position_m) + " m, " +
            FormatDouble(threshold.rotation_deg) + " deg)";
  f.x_label = "mean crowdedness of the queries (% person pixels)";
  f.y_label = "queries localized (%)";
  f.y_min = 0;
  f.y_max = 100;
  f.x_min = 0;
  if (sets.empty()) return f;
  for (size_t m = 0; m < sets.front().methods.size(); ++m) {
    plot::Series s;
    s.label = sets.front().methods[m].method;
    s.markers = true;
    for (const SweepSet& set : sets) {
      s.x.push_back(MeanCrowdedness(set));
      s.y.push_back(100 * evaluation::Recall(set.methods[m].errors, threshold));
    }
    f.series.push_back(std::move(s));
  }
  return f;
}

}  // namespace locforge::analysis

// Recall against crowdedness over several query sets of one map (the same
// query routes re-simulated at several crowd densities): the controlled
// experiment behind the paper's Table 6. Each set's queries are joined with
// their content (analysis/image_content: crowdedness from person masks).
#ifndef LOCFORGE_PLUGINS_ANALYSIS_CONTENT_CROWD_SWEEP_H_
#define LOCFORGE_PLUGINS_ANALYSIS_CONTENT_CROWD_SWEEP_H_

#include <string>
#include <vector>

#include "image_content.h"
#include "locforge/plot.h"

namespace locforge::analysis {

// One query set: the density it was simulated at, its queries' content and
// every method's errors on it (the same methods, in the same order, in every
// set).
struct SweepSet {
  double setting = 0;  // people per 100 m^2 of floor
  std::vector<ImageContent> content;
  std::vector<MethodErrors> methods;
};

// Throws InputError when a set's methods differ from the first set's, or a
// query has no content row (a partial join would bias the sweep).
void CheckSweep(const std::vector<SweepSet>& sets);

// Mean crowdedness (% person pixels) of the set's queries with a mask.
double MeanCrowdedness(const SweepSet& set);

// One row per set: setting, queries, mean crowdedness, share of crowded
// queries, then each method's recalls "a / b / c" at `thresholds`.
evaluation::Table SweepTable(const std::vector<SweepSet>& sets, const std::vector<evaluation::Threshold>& thresholds);

// All sets pooled, queries binned by their own crowdedness (bin edges in %,
// ascending; the last bin is open): one row per bin, the recalls per method.
evaluation::Table BinnedTable(const std::vector<SweepSet>& sets, const std::vector<double>& edges_percent,
                              const std::vector<evaluation::Threshold>& thresholds);

// Recall (%) at `threshold` against the sets' mean crowdedness, one line per method.
plot::Figure SweepFigure(const std::vector<SweepSet>& sets, const evaluation::Threshold& threshold);

}  // namespace locforge::analysis

#endif  // LOCFORGE_PLUGINS_ANALYSIS_CONTENT_CROWD_SWEEP_H_

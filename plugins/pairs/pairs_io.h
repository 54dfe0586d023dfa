// pairs.txt (kapture.pairs) is kapture-localization's list: a
// "# query_image, map_image, score" header then one pair a line. Retrieval
// pairs are ordered by query, then by decreasing score (ties by name).
#ifndef LOCFORGE_PLUGINS_PAIRS_PAIRS_IO_H_
#define LOCFORGE_PLUGINS_PAIRS_PAIRS_IO_H_

#include <algorithm>
#include <iterator>
#include <ostream>
#include <string>
#include <vector>

#include "locforge/fs.h"
#include "locforge/kapture/csv.h"

namespace locforge::retrieval {

namespace k = locforge::kapture;

struct ScoredPair {
  std::string query, map;
  double score = 0;
};

inline constexpr char kPairsHeader[] = "# query_image, map_image, score\n";

// The pairs' lines of pairs.txt, without the header.
inline void WritePairLines(std::ostream& out, const std::vector<ScoredPair>& pairs) {
  for (const auto& p : pairs) out << p.query << ", " << p.map << ", " << k::FormatDouble(p.score) << "\n";
}

inline void WritePairs(const fs::path& out_dir, const std::vector<ScoredPair>& pairs) {
  AtomicFile file(out_dir / "pairs.txt", false);
  file.stream() << kPairsHeader;
  WritePairLines(file.stream(), pairs);
  file.Commit();
}

inline std::vector<std::string> Intersect(const std::vector<std::string>& sorted_a,
                                   const std::vector<std::string>& sorted_b) {
  std::vector<std::string> out;
  std::set_intersection(sorted_a.begin(), sorted_a.end(), sorted_b.begin(), sorted_b.end(),
                        std::back_inserter(out));
  return out;
}

}  // namespace locforge::retrieval

#endif  // LOCFORGE_PLUGINS_PAIRS_PAIRS_IO_H_

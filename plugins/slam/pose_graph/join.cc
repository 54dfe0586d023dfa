#include "join.h"

#include <algorithm>
#include <numeric>
#include <set>
#include <sstream>

namespace locforge::lidar {

std::vector<JoinHypothesis> ClusterHypotheses(const std::vector<JoinCandidate>& c,
                                              const JoinConsensusOptions& agreement) {
  std::vector<int> order(c.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int x, int y) { return c[x].overlap > c[y].overlap; });
  std::vector<char> assigned(c.size(), 0);
  std::vector<JoinHypothesis> out;
  for (int i : order) {
    if (assigned[i]) continue;
    JoinHypothesis h;
    h.T_A_B = c[i].T_A_B;
    std::set<int> bs;
    for (int j : order)
      if (!assigned[j] && HypothesesAgree(c[i], c[j], agreement)) {
        assigned[j] = 1;
        h.loops.push_back(j);
        bs.insert(c[j].b);
      }
    h.support = static_cast<int>(bs.size());
    out.push_back(std::move(h));
  }
  return out;
}

bool JoinDecisionOptions::Check(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(max_conflict >= 0 && max_conflict <= 1)) return fail("max_conflict must be in [0, 1]");
  if (min_agreeing < 1) return fail("min_agreeing must be >= 1");
  if (!(rival_conflict_ratio >= 1)) return fail("rival_conflict_ratio must be >= 1");
  if (!(rival_conflict_margin >= 0)) return fail("rival_conflict_margin must be >= 0");
  if (!(rival_overlap >= 0 && rival_overlap <= 1)) return fail("rival_overlap must be in [0, 1]");
  return true;
}

const char* ToString(JoinDecision::Status status) {
  switch (status) {
    case JoinDecision::Status::kJoined: return "joined";
    case JoinDecision::Status::kAmbiguous: return "ambiguous";
    case JoinDecision::Status::kNoEvidence: return "no_evidence";
  }
  return "?";
}

namespace {

// Structure that agrees, less what a wrong frame would put in free space
// (each conflicting cell outweighs several agreeing ones).
double Quality(const JoinEvidence& e) {
  const int64_t conflicting = e.b_in_a.conflicting + e.a_in_b.conflicting;
  return static_cast<double>(e.Agreeing()) - 2.0 * static_cast<double>(conflicting);
}

std::string Describe(const JoinHypothesis& h) {
  std::ostringstream s;
  s.precision(3);
  s << "conflict " << h.evidence.Conflict() << " over " << h.evidence.Agreeing() << " agreeing cells, "
    << h.support << " loop keyframes";
  return s.str();
}

}  // namespace

JoinDecision DecideJoin(const std::vector<JoinHypothesis>& h, const JoinDecisionOptions& o) {
  JoinDecision d;
  auto eligible = [&](const JoinHypothesis& x) {
    return x.evidence.Conflict() <= o.max_conflict && x.evidence.Agreeing() >= o.min_agreeing;
  };
  // The best hypothesis: eligible first, then by quality.
  for (int i = 0; i < static_cast<int>(h.size()); ++i) {
    if (d.winner < 0) {
      d.winner = i;
      continue;
    }
    const bool ei = eligible(h[i]), ew = eligible(h[d.winner]);
    if (ei != ew ? ei : Quality(h[i].evidence) > Quality(h[d.winner].evidence)) d.winner = i;
  }
  if (d.winner < 0) {
    d.reason = "no loop between them";
    return d;
  }
  const JoinHypothesis& w = h[d.winner];
  if (!eligible(w)) {
    d.reason = "no hypothesis explains the overlap (best: " + Describe(w) + ")";
    return d;
  }
  // The closest distinct rival.
  for (int i = 0; i < static_cast<int>(h.size()); ++i) {
    if (i == d.winner || !eligible(h[i])) continue;
    const bool close = h[i].evidence.Conflict() <= o.rival_conflict_ratio * w.evidence.Conflict() +
                                                       o.rival_conflict_margin &&
                       h[i].evidence.Agreeing() >= o.rival_overlap * static_cast<double>(w.evidence.Agreeing());
    if (close && (d.rival < 0 || Quality(h[i].evidence) > Quality(h[d.rival].evidence))) d.rival = i;
  }
  if (d.rival >= 0) {
    d.status = JoinDecision::Status::kAmbiguous;
    d.reason = "two frames explain the overlap: " + Describe(w) + "; rival " + Describe(h[d.rival]);
    return d;
  }
  d.status = JoinDecision::Status::kJoined;
  d.reason = Describe(w);
  return d;
}

}  // namespace locforge::lidar

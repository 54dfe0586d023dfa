#include "join.h"

#include <cmath>

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
  if (!(max_start_offset_m >= 0)) return fail("max_start_offset_m must be >= 0");
  if (!(alias_conflict >= max_conflict && alias_conflict <= 1))
    return fail("alias_conflict must be in [max_conflict, 1]");
  if (!(alias_min_shift_m > 0)) return fail("alias_min_shift_m must be > 0");
  if (!(alias_max_rotation_deg > 0)) return fail("alias_max_rotation_deg must be > 0");
  if (max_trials < 0) return fail("max_trials must be >= 0");
  if (!(trial_max_conflict >= 0 && trial_max_conflict <= 1)) return fail("trial_max_conflict must be in [0, 1]");
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

// Two frames turned alike but shifted by more than the clustering's reach:
// the same overlap read one repeated room apart.
static bool ShiftedCopies(const JoinHypothesis& x, const JoinHypothesis& y, const JoinDecisionOptions& o) {
  const double angle = Eigen::AngleAxisd(x.T_A_B.q.conjugate() * y.T_A_B.q).angle() * 180.0 / M_PI;
  return angle <= o.alias_max_rotation_deg && (x.T_A_B.t - y.T_A_B.t).norm() >= o.alias_min_shift_m;
}

static bool Explains(const JoinHypothesis& x, const JoinDecisionOptions& o) {
  return x.evidence.Conflict() <= o.max_conflict && x.evidence.Agreeing() >= o.min_agreeing;
}

// Repeated structure: a frame that explains the overlap has a shifted copy
// that nearly does. The overlap then does not fix the translation; only
// frames keeping the starts together are answers (none without the prior).
static bool Repeated(const std::vector<JoinHypothesis>& h, const JoinDecisionOptions& o) {
  for (size_t i = 0; i < h.size(); ++i)
    for (size_t k = 0; k < h.size(); ++k)
      if (i != k && Explains(h[i], o) && h[k].evidence.Conflict() <= o.alias_conflict &&
          h[k].evidence.Agreeing() >= o.min_agreeing && ShiftedCopies(h[i], h[k], o))
        return true;
  return false;
}

static bool NearStarts(const JoinHypothesis& x, const JoinDecisionOptions& o) {
  return o.max_start_offset_m > 0 && x.start_offset_m <= o.max_start_offset_m;
}

JoinDecision DecideJoin(const std::vector<JoinHypothesis>& h, const JoinDecisionOptions& o) {
  JoinDecision d;
  auto explains = [&](const JoinHypothesis& x) { return Explains(x, o); };
  const bool repeated = Repeated(h, o);
  auto near_starts = [&](const JoinHypothesis& x) { return !repeated || NearStarts(x, o); };
  auto eligible = [&](const JoinHypothesis& x) { return explains(x) && near_starts(x); };
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
    if (!explains(w)) {
      d.reason = "no hypothesis explains the overlap (best: " + Describe(w) + ")";
    } else {
      std::ostringstream r;
      r.precision(3);
      r << "repeated structure: frames one repeat apart explain the overlap alike, so it does not fix where the "
           "part lies, and ";
      if (o.max_start_offset_m > 0)
        r << "no such frame keeps the sequences' starts within " << o.max_start_offset_m << " m (best: "
          << Describe(w) << ", start offset " << w.start_offset_m << " m)";
      else
        r << "the starts are not used (join_max_start_offset_m 0)";
      d.status = JoinDecision::Status::kAmbiguous;
      d.reason = r.str();
    }
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
  if (repeated) d.reason += " (repeated structure: the one that keeps the sequences' starts together)";
  return d;
}

}  // namespace locforge::lidar

namespace locforge::lidar {

std::vector<int> TrialCandidates(const std::vector<JoinHypothesis>& h, const JoinDecisionOptions& o) {
  // A frame DecideJoin could take (explains the overlap, and keeps the starts
  // together if the structure repeats): it has decided.
  const bool repeated_explained = Repeated(h, o);
  for (const auto& x : h)
    if (Explains(x, o) && (!repeated_explained || NearStarts(x, o))) return {};
  std::vector<int> close;
  for (int i = 0; i < static_cast<int>(h.size()); ++i)
    if (h[i].evidence.Conflict() <= o.trial_max_conflict && h[i].evidence.Agreeing() >= o.min_agreeing)
      close.push_back(i);
  // Shifted copies (among the close frames too): the overlap does not fix
  // the translation, so only frames keeping the starts together may be tried
  // (none without that prior).
  bool repeated = repeated_explained;
  for (int i : close)
    for (int k : close) repeated = repeated || (i != k && ShiftedCopies(h[i], h[k], o));
  if (repeated)
    close.erase(std::remove_if(close.begin(), close.end(), [&](int i) { return !NearStarts(h[i], o); }), close.end());
  std::stable_sort(close.begin(), close.end(),
                   [&](int x, int y) { return h[x].evidence.Conflict() < h[y].evidence.Conflict(); });
  if (static_cast<int>(close.size()) > o.max_trials) close.resize(o.max_trials);
  return close;
}

JoinDecision DecideAfterTrials(const std::vector<JoinHypothesis>& h, const JoinDecision& before,
                               const JoinDecisionOptions& o) {
  std::vector<int> tried, held;
  for (int i = 0; i < static_cast<int>(h.size()); ++i) {
    if (!h[i].tried) continue;
    tried.push_back(i);
    if (h[i].after.Conflict() <= o.max_conflict && h[i].after.Agreeing() >= o.min_agreeing) held.push_back(i);
  }
  if (tried.empty()) return before;
  std::stable_sort(held.begin(), held.end(),
                   [&](int x, int y) { return Quality(h[x].after) > Quality(h[y].after); });
  auto after = [&](int i) {
    std::ostringstream s;
    s.precision(3);
    s << "conflict " << h[i].evidence.Conflict() << " as the parts stood, " << h[i].after.Conflict()
      << " over " << h[i].after.Agreeing() << " agreeing cells once joined and optimised";
    return s.str();
  };
  JoinDecision d = before;
  if (held.size() == 1) {
    d.status = JoinDecision::Status::kJoined;
    d.winner = held.front();
    d.rival = -1;
    d.reason = "on trial: " + after(d.winner) + ", the only one of " + std::to_string(tried.size()) +
               " frames tried that holds";
  } else if (held.size() > 1) {
    d.status = JoinDecision::Status::kAmbiguous;
    d.winner = held[0];
    d.rival = held[1];
    d.reason = "two frames explain the overlap once joined on trial: " + after(held[0]) + "; rival " + after(held[1]);
  } else {
    std::ostringstream s;
    s << d.reason << "; " << tried.size() << " frame(s) tried, none holds once joined (best: " << after(tried.front())
      << ")";
    d.reason = s.str();
  }
  return d;
}

}  // namespace locforge::lidar

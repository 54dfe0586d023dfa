// Joining the parts of the map (slam.h): candidate loops between two parts,
// the frames they suggest, the decision on the whole overlap (join.h), and
// the check of every join once the graph is optimised.
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <map>
#include <sstream>

#include "slam.h"

namespace locforge::lidar {

namespace {

// A frame as "x, y, yaw" (m, m, deg), rounded for the log.
std::string FrameXYYaw(const Pose& T) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(2) << T.t.x() << ", " << T.t.y() << ", " << std::setprecision(1)
    << YawOf(T) * 180.0 / M_PI;
  return s.str();
}

std::string Percent(double f) {
  std::ostringstream s;
  s.precision(3);
  s << 100 * f << " %";
  return s.str();
}

}  // namespace

std::vector<const Keyframe*> Slam::KeyframesOf(int component) const {
  std::vector<const Keyframe*> out;
  for (const auto& kf : keyframes_)
    if (component_.at(kf.sequence) == component) out.push_back(&kf);
  return out;
}

std::string Slam::NameOf(int component) const {
  std::vector<std::string> names;  // in time order
  for (const auto& kf : keyframes_)
    if (component_.at(kf.sequence) == component && std::find(names.begin(), names.end(), kf.sequence) == names.end())
      names.push_back(kf.sequence);
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : "+") + n;
  return out;
}

FloorGrid Slam::MakeFloor(const std::vector<const Keyframe*>& kfs) const {
  FloorGridOptions fo;
  fo.agreement_margin_m = o_.join_free_space_margin_m;
  Eigen::AlignedBox2d box;
  for (const Keyframe* k : kfs) {
    const Eigen::Vector2d p = graph_.nodes.at(k->id).t.head<2>();
    box.extend(p - Eigen::Vector2d::Constant(fo.max_range_m + 1));
    box.extend(p + Eigen::Vector2d::Constant(fo.max_range_m + 1));
  }
  FloorGrid g(fo, box);
  for (const Keyframe* k : kfs) g.AddScan(*CloudOf(*k), graph_.nodes.at(k->id));
  g.Finish();
  return g;
}

const FloorGrid& Slam::FloorOf(int component) {
  auto it = floors_.find(component);
  if (it == floors_.end() || it->second.first != poses_version_)
    it = floors_.insert_or_assign(component, std::make_pair(poses_version_, MakeFloor(KeyframesOf(component)))).first;
  return it->second.second;
}

int Slam::JoinComponents(int round) {
  int joined = 0;
  const int anchor = AnchorComponent();
  for (bool progress = true; progress;) {
    progress = false;
    std::set<int> components;  // by first keyframe: in time order
    std::map<int, size_t> sizes;
    for (const auto& kf : keyframes_) ++sizes[component_.at(kf.sequence)];
    for (const auto& [seq, c] : component_) components.insert(c);
    // Each part B to the anchor's, else to an earlier part (two sequences
    // that overlap each other more than the rest join first, then together);
    // a pair that failed is tried again only once either grew.
    for (const int B : components) {
      if (B == anchor) continue;
      std::vector<int> targets = {anchor};
      for (const int A : components)
        if (A != anchor && A < B) targets.push_back(A);
      for (const int A : targets) {
        const std::pair<size_t, size_t> state(sizes[A], sizes[B]);
        const auto failed = join_failed_.find({A, B});
        if (failed != join_failed_.end() && failed->second == state) continue;
        if (TryJoin(A, B, round)) {
          ++joined;
          progress = true;
          break;
        }
        join_failed_[{A, B}] = state;
      }
      if (progress) break;  // parts changed: enumerate again
    }
  }
  return joined;
}

// Where each sequence of a part starts (its first keyframe), in the part's frame.
std::vector<Eigen::Vector3d> Slam::SequenceStarts(const std::vector<const Keyframe*>& part) const {
  std::map<std::string, const Keyframe*> first;
  for (const Keyframe* k : part)
    if (!first.count(k->sequence) || k->timestamp < first[k->sequence]->timestamp) first[k->sequence] = k;
  std::vector<Eigen::Vector3d> starts;
  for (const auto& [sequence, k] : first) starts.push_back(graph_.nodes.at(k->id).t);
  return starts;
}

// The farthest start of B from its nearest start of A, with B in A's frame by T_A_B.
static double StartOffset(const std::vector<Eigen::Vector3d>& starts_a, const std::vector<Eigen::Vector3d>& starts_b,
                          const Pose& T_A_B) {
  double worst = 0;
  for (const auto& b : starts_b) {
    double nearest = std::numeric_limits<double>::infinity();
    for (const auto& a : starts_a) nearest = std::min(nearest, (T_A_B * b - a).norm());
    worst = std::max(worst, nearest);
  }
  return worst;
}

// Joins part B to part A, in named steps: seeds -> places -> rough queue ->
// headings the places found, seeded too -> judge the frames by the whole
// overlap (join.h) -> trials of the close ones -> decide and apply.
//
// Candidate loops: seeds (B's keyframes near its start against A's nearest
// keyframe under every turn about that start: sequences often start at one
// spot, heading unknown) and places (Scan Context over all keyframes). Each
// distinct frame they suggest is judged by the two maps' whole overlap; the
// winner's predicted loops along B are then tested, and B moves into A's
// frame with the loops that agree.
//
// Loops between the parts take the rough step only, until a frame is chosen
// (the overlap evidence needs no more); then the precise step for the loops
// that agree with it.
struct Slam::JoinPlan {
  std::vector<int> inliers;
  Pose H;
  int predicted_tested = 0, predicted_found = 0;
  std::string failure;  // empty: its loops hold
};

struct Slam::JoinSearch {
  int A = 0, B = 0;
  JoinAttempt at;
  std::vector<const Keyframe*> ka, kb;
  std::vector<JoinCandidate> candidates;
  std::vector<RegistrationResult> results;  // parallel: rough, or precise when `fine`
  std::vector<char> fine;
  std::set<std::pair<int, int>> tested;
  // Rough checks are queued, then run (side by side when there are worker
  // registrars) and their loops added in the order they were queued: the
  // same candidates as checking each at once.
  struct RoughTask {
    const Keyframe* a;
    const Keyframe* b;
    std::vector<Pose> guesses;
    std::vector<RegistrationResult> found;
  };
  std::vector<RoughTask> queued;
  Eigen::Vector3d p0;                       // B's start
  std::vector<const Keyframe*> near_start;  // B's keyframes near p0, nearest first
  std::vector<double> turns;                // the headings every seed is tried from
  int seeds = 0, places = 0;
  JoinConsensusOptions agreement;
  JoinDecisionOptions decision;
  std::vector<JoinHypothesis> hypotheses;
  std::map<int, JoinPlan> plans;  // by hypothesis
};

namespace {

JoinConsensusOptions AgreementOf(const SlamOptions& o) {
  JoinConsensusOptions agreement;
  agreement.max_translation = o.join_max_translation_m;
  agreement.max_rotation_deg = o.join_max_rotation_deg;
  return agreement;
}

// cell_m: the floor grids' cell, the unit of join_min_overlap_m's count.
JoinDecisionOptions DecisionOptionsOf(const SlamOptions& o, double cell_m) {
  JoinDecisionOptions jo;
  jo.max_conflict = o.join_max_conflict;
  jo.max_start_offset_m = o.join_max_start_offset_m;
  jo.alias_conflict = std::max(o.join_alias_conflict, o.join_max_conflict);
  jo.alias_min_shift_m = o.join_alias_min_shift_m;
  jo.alias_max_rotation_deg = o.join_max_rotation_deg;
  jo.min_agreeing = std::max<int64_t>(1, std::llround(o.join_min_overlap_m / cell_m));
  jo.rival_conflict_ratio = o.join_rival_conflict_ratio;
  jo.rival_conflict_margin = o.join_rival_conflict_margin;
  jo.rival_overlap = o.join_rival_overlap;
  jo.max_trials = o.join_trials;
  jo.trial_max_conflict = o.join_trial_max_conflict;
  return jo;
}

// The log line of a join attempt (at.frames: its hypotheses).
std::string JoinLog(const JoinAttempt& at, int seeds, int places, size_t loops, const JoinDecision& d) {
  const std::vector<JoinHypothesis>& hypotheses = at.frames;
  std::ostringstream log;
  log << "pose_graph: join " << at.b << " to " << at.a << ": " << seeds << " seeds, " << places << " places, "
      << loops << " loops, " << hypotheses.size() << " frames";
  if (at.winner >= 0)
    log << "; best: conflict " << Percent(JoinAttempt::Decisive(hypotheses[at.winner]).Conflict()) << ", "
        << JoinAttempt::Decisive(hypotheses[at.winner]).Agreeing()
        << " cells agree";
  if (at.rival >= 0)
    log << "; rival: conflict " << Percent(JoinAttempt::Decisive(hypotheses[at.rival]).Conflict()) << ", "
        << JoinAttempt::Decisive(hypotheses[at.rival]).Agreeing()
        << " cells";
  log << "; frames (conflict, agreeing, support; x m, y m, yaw deg of b's frame in a's; farthest start of b from a's):";
  for (const auto& h : hypotheses) {
    log << " (" << Percent(h.evidence.Conflict()) << ", " << h.evidence.Agreeing() << ", " << h.support << "; "
        << FrameXYYaw(h.T_A_B) << "; start " << std::setprecision(3) << h.start_offset_m << " m";
    if (h.tried) log << "; on trial: " << Percent(h.after.Conflict()) << ", " << h.after.Agreeing();
    log << ")";
  }
  if (at.predicted_tested > 0) log << "; predicted loops " << at.predicted_found << " of " << at.predicted_tested;
  log << ": " << (d.status == JoinDecision::Status::kJoined ? "joined" : "refused, " + d.reason);
  return log.str();
}

}  // namespace

// Headings the places found, tried at the start too: a rough check starts
// from the turns, up to half a step off, and may not reach a heading between
// them, while a place elsewhere in a floor of repeated rooms can find the
// heading with the wrong translation.
std::vector<double> PlaceHeadings(const std::vector<JoinCandidate>& candidates, const std::vector<double>& turns,
                                  double max_rotation_deg) {
  const double tolerance = max_rotation_deg * M_PI / 180;
  auto near = [&](double yaw, auto begin, auto end) {
    return std::any_of(begin, end, [&](double k) { return std::abs(std::remainder(yaw - k, 2 * M_PI)) < tolerance; });
  };
  std::vector<double> yaws, place_yaws;
  for (const auto& c : candidates) yaws.push_back(YawOf(c.T_A_B));
  for (size_t i = 0; i < yaws.size(); ++i) {
    const double y = yaws[i];
    if (!near(y, yaws.begin(), yaws.begin() + i) && near(y, yaws.begin() + i + 1, yaws.end()) &&
        !near(y, turns.begin(), turns.end()) && !near(y, place_yaws.begin(), place_yaws.end()))
      place_yaws.push_back(y);
  }
  return place_yaws;
}

bool Slam::TryJoin(int A, int B, int round) {
  ++stats_.join_attempts;
  JoinSearch s;
  s.A = A;
  s.B = B;
  s.at.round = round;
  s.at.a = NameOf(A);
  s.at.b = NameOf(B);
  s.ka = KeyframesOf(A);
  s.kb = KeyframesOf(B);
  s.p0 = graph_.nodes.at(s.kb.front()->id).t;
  s.near_start = NearStart(s.kb, s.p0);
  for (int h = 0; h < o_.loop_yaw_hypotheses; ++h) s.turns.push_back(2 * M_PI * h / o_.loop_yaw_hypotheses);
  QueueSeeds(s, s.turns);
  QueuePlaces(s);
  RunRoughQueue(s);
  QueueSeeds(s, PlaceHeadings(s.candidates, s.turns, o_.join_max_rotation_deg));
  RunRoughQueue(s);
  JoinDecision d = JudgeFrames(s);
  if (d.status != JoinDecision::Status::kJoined) RunJoinTrials(s, &d);
  return FinishJoin(s, d);
}

// A's keyframe nearest p within loop_radius_m (null: none).
const Keyframe* Slam::NearestKeyframe(const std::vector<const Keyframe*>& part, const Eigen::Vector3d& p) const {
  const Keyframe* best = nullptr;
  double best_d = o_.loop_radius_m;
  for (const Keyframe* a : part) {
    const double d = (graph_.nodes.at(a->id).t - p).norm();
    if (d <= best_d) best_d = d, best = a;
  }
  return best;
}

// The keyframes of `part` within join_seed_radius_m of p0, nearest first.
std::vector<const Keyframe*> Slam::NearStart(const std::vector<const Keyframe*>& part,
                                             const Eigen::Vector3d& p0) const {
  std::vector<const Keyframe*> near_start;
  for (const Keyframe* b : part)
    if ((graph_.nodes.at(b->id).t - p0).norm() <= o_.join_seed_radius_m) near_start.push_back(b);
  std::stable_sort(near_start.begin(), near_start.end(), [&](const Keyframe* x, const Keyframe* y) {
    return (graph_.nodes.at(x->id).t - p0).norm() < (graph_.nodes.at(y->id).t - p0).norm();
  });
  return near_start;
}

void Slam::AddJoinCandidate(JoinSearch& s, const Keyframe& a, const Keyframe& b, const RegistrationResult& r,
                            bool predicted, bool precise) const {
  JoinCandidate c;
  c.a = a.id;
  c.b = b.id;
  c.T_A_B = graph_.nodes.at(a.id) * r.T_target_source * graph_.nodes.at(b.id).Inverse();
  c.p_b = graph_.nodes.at(b.id).t;
  c.overlap = r.inlier_fraction;
  c.predicted = predicted;
  s.candidates.push_back(c);
  s.results.push_back(r);
  s.fine.push_back(precise);
}

void Slam::QueueRoughCheck(JoinSearch& s, const Keyframe& a, const Keyframe& b, const std::vector<Pose>& guesses) {
  s.tested.insert({a.id, b.id});
  ++stats_.join_tests;
  s.queued.push_back(JoinSearch::RoughTask{&a, &b, guesses, {}});
}

void Slam::RunRoughQueue(JoinSearch& s) {
  const LoopCheckOptions lo = LoopOptions(o_.join_rough_error);
  auto check = [&](JoinSearch::RoughTask& t, const Registrar& registrar) {
    t.found = RoughCheck(registrar, *t.a, *t.b, t.guesses, lo);
  };
  if (!ForEachOnWorkers(s.queued.size(), [&](size_t n, size_t w) { check(s.queued[n], workers_[w].first); }, ""))
    for (JoinSearch::RoughTask& t : s.queued) {
      hooks_.check_cancelled();
      check(t, registrar_);
    }
  for (const JoinSearch::RoughTask& t : s.queued)
    for (const auto& r : t.found) AddJoinCandidate(s, *t.a, *t.b, r, false, false);
  s.queued.clear();
}

// Seeds: B's keyframes near its start p0, every loop_stride-th, nearest
// first; for each turn H about p0, against the keyframe of A nearest H p_b,
// from the guess T_ab = T_A_a^-1 H T_B_b.
void Slam::QueueSeeds(JoinSearch& s, const std::vector<double>& yaws) {
  int n = 0;
  for (size_t i = 0; i < s.near_start.size() && n < o_.join_seeds; i += o_.loop_stride, ++n) {
    hooks_.check_cancelled();
    const Keyframe& b = *s.near_start[i];
    std::map<int, std::vector<Pose>> guesses;  // a -> guesses
    for (double yaw : yaws) {
      const Pose H =
          Pose(Eigen::Quaterniond::Identity(), s.p0) * YawPose(yaw) * Pose(Eigen::Quaterniond::Identity(), -s.p0);
      const Keyframe* a = NearestKeyframe(s.ka, H * graph_.nodes.at(b.id).t);
      if (a) guesses[a->id].push_back(graph_.nodes.at(a->id).Inverse() * H * graph_.nodes.at(b.id));
    }
    for (const auto& [a, g] : guesses) QueueRoughCheck(s, keyframes_[a], b, g);
  }
  s.seeds = std::max(s.seeds, n);
}

// Places: for every loop_stride-th keyframe of B, A's keyframes nearest by
// ring key, the best of them by Scan Context distance, checked from the
// heading that distance found.
void Slam::QueuePlaces(JoinSearch& s) {
  for (size_t i = 0; i < s.kb.size(); i += o_.loop_stride) {
    hooks_.check_cancelled();
    const Keyframe& b = *s.kb[i];
    std::vector<std::pair<double, const Keyframe*>> ranked;
    for (const Keyframe* a : s.ka) ranked.emplace_back(RingKeyDistance(a->context, b.context), a);
    const size_t top = std::min<size_t>(ranked.size(), o_.join_place_candidates);
    std::partial_sort(ranked.begin(), ranked.begin() + top, ranked.end(),
                      [](const auto& x, const auto& y) { return x.first < y.first; });
    std::vector<std::pair<ScanContextMatch, const Keyframe*>> matches;
    for (size_t k = 0; k < top; ++k) {
      const ScanContextMatch m = CompareScanContexts(ranked[k].second->context, b.context);
      if (m.distance <= o_.join_place_max_distance) matches.emplace_back(m, ranked[k].second);
    }
    std::stable_sort(matches.begin(), matches.end(),
                     [](const auto& x, const auto& y) { return x.first.distance < y.first.distance; });
    for (size_t k = 0; k < matches.size() && static_cast<int>(k) < o_.join_place_matches; ++k) {
      const Keyframe& a = *matches[k].second;
      if (s.tested.count({a.id, b.id})) continue;
      QueueRoughCheck(s, a, b, {YawPose(matches[k].first.yaw)});
      ++s.places;
    }
  }
}

// The frames the loops suggest, each judged by the two maps' whole overlap
// and the offset of B's starts from A's; the decision as the parts stand.
JoinDecision Slam::JudgeFrames(JoinSearch& s) {
  s.agreement = AgreementOf(o_);
  s.hypotheses = ClusterHypotheses(s.candidates, s.agreement);
  const FloorGrid& fa = FloorOf(s.A);
  const FloorGrid& fb = FloorOf(s.B);
  for (auto& h : s.hypotheses) h.evidence = EvaluateJoin(fa, fb, h.T_A_B);
  const std::vector<Eigen::Vector3d> starts_a = SequenceStarts(s.ka), starts_b = SequenceStarts(s.kb);
  for (auto& h : s.hypotheses) h.start_offset_m = StartOffset(starts_a, starts_b, h.T_A_B);
  s.decision = DecisionOptionsOf(o_, fa.options().cell_m);
  JoinDecision d = DecideJoin(s.hypotheses, s.decision);
  s.at.candidates = static_cast<int>(s.candidates.size());
  s.at.hypotheses = static_cast<int>(s.hypotheses.size());
  return d;
}

// The loops of hypothesis w, made precise (added as new candidates).
void Slam::MakeLoopsPrecise(JoinSearch& s, int w) {
  for (int i : s.hypotheses[w].loops) {
    hooks_.check_cancelled();
    RegistrationResult precise;
    if (!FineCheck(registrar_, MakeRefiner(), [this](const Keyframe& k) { return CloudOf(k); },
                   keyframes_[s.candidates[i].a], keyframes_[s.candidates[i].b],
                   s.results[i], LoopOptions(o_.join_rough_error), &precise))
      continue;
    const Keyframe& a = keyframes_[s.candidates[i].a];
    const Keyframe& b = keyframes_[s.candidates[i].b];
    AddJoinCandidate(s, a, b, precise, false, true);
  }
}

// The loops frame H predicts along B (B's keyframes against A's nearest, not
// tested yet, at most join_verify spread evenly), checked: how many were tested.
size_t Slam::TestPredictedLoops(JoinSearch& s, const Pose& H) {
  std::vector<std::pair<const Keyframe*, const Keyframe*>> predicted;
  for (const Keyframe* b : s.kb) {
    const Keyframe* a = NearestKeyframe(s.ka, H * graph_.nodes.at(b->id).t);
    if (a && !s.tested.count({a->id, b->id})) predicted.emplace_back(a, b);
  }
  const size_t n = std::min<size_t>(predicted.size(), o_.join_verify);
  for (size_t k = 0; k < n; ++k) {
    hooks_.check_cancelled();
    const auto [a, b] = predicted[k * predicted.size() / n];
    s.tested.insert({a->id, b->id});
    ++stats_.join_tests;
    for (const auto& r : CheckLoop(*a, *b, {graph_.nodes.at(a->id).Inverse() * H * graph_.nodes.at(b->id)},
                                   o_.loop_rough_error))
      AddJoinCandidate(s, *a, *b, r, true, true);
  }
  return n;
}

// A frame's loops made precise, then the loops it predicts along B; the
// precise loops agreeing with it, and the frame of the best-overlapping one.
const Slam::JoinPlan& Slam::PlanOf(JoinSearch& s, int w) {
  if (s.plans.count(w)) return s.plans.at(w);
  JoinPlan p;
  const JoinCandidate rep = s.candidates[s.hypotheses[w].loops.front()];
  MakeLoopsPrecise(s, w);
  p.H = rep.T_A_B;
  const size_t n = TestPredictedLoops(s, p.H);
  std::set<int> support, verified;
  int best = -1;
  for (int i = 0; i < static_cast<int>(s.candidates.size()); ++i)
    if (s.fine[i] && HypothesesAgree(rep, s.candidates[i], s.agreement)) {
      p.inliers.push_back(i);
      support.insert(s.candidates[i].b);
      if (s.candidates[i].predicted) verified.insert(s.candidates[i].b);
      if (best < 0 || s.candidates[i].overlap > s.candidates[best].overlap) best = i;
    }
  if (best >= 0) p.H = s.candidates[best].T_A_B;
  p.predicted_tested = static_cast<int>(n);
  p.predicted_found = static_cast<int>(verified.size());
  if (static_cast<int>(support.size()) < o_.join_min_support ||
      static_cast<int>(verified.size()) < o_.join_min_verified)
    p.failure = "the frame explains the overlap but its loops do not hold: " + std::to_string(support.size()) +
                " keyframes agree, " + std::to_string(verified.size()) + " of " + std::to_string(n) +
                " predicted loops found";
  return s.plans.emplace(w, std::move(p)).first->second;
}

// B into A's frame by a plan (and its pre-optimisation copy, for the plot).
void Slam::ApplyJoin(JoinSearch& s, const JoinPlan& p) {
  for (const Keyframe* b : s.kb) {
    graph_.nodes[b->id] = p.H * graph_.nodes.at(b->id);
    before_.nodes[b->id] = p.H * before_.nodes.at(b->id);
  }
  for (int i : p.inliers) {
    const Keyframe& a = keyframes_[s.candidates[i].a];
    const Keyframe& b = keyframes_[s.candidates[i].b];
    if (!accepted_.count({std::min(a.id, b.id), std::max(a.id, b.id)})) AddLoopEdge(a, b, s.results[i]);
  }
  for (auto& [seq, c] : component_)
    if (c == s.B) c = s.A;
  ++poses_version_;
}

// Trials: no frame explains the overlap as the parts stand; the close ones
// are joined on a copy of the state, optimised, and judged again.
void Slam::RunJoinTrials(JoinSearch& s, JoinDecision* d) {
  const std::vector<int> trials = TrialCandidates(s.hypotheses, s.decision);
  for (int w : trials) {
    const JoinPlan& p = PlanOf(s, w);
    if (!p.failure.empty()) continue;
    const PoseGraph graph = graph_, before = before_;
    const std::set<std::pair<int, int>> accepted = accepted_;
    const std::map<std::string, int> component = component_;
    const int version = poses_version_;
    const PoseGraphSummary summary = stats_.summary;
    ApplyJoin(s, p);
    Optimize();
    s.hypotheses[w].tried = true;
    s.hypotheses[w].after = EvaluateJoin(MakeFloor(s.ka), MakeFloor(s.kb), Pose());
    graph_ = graph, before_ = before, accepted_ = accepted, component_ = component;
    poses_version_ = version, stats_.summary = summary;
    ++stats_.join_trials;
  }
  *d = DecideAfterTrials(s.hypotheses, *d, s.decision);
}

// The winner's loops must hold too; the attempt logged and recorded, and B
// moved into A's frame when joined.
bool Slam::FinishJoin(JoinSearch& s, JoinDecision d) {
  JoinAttempt& at = s.at;
  Pose H;
  std::vector<int> inliers;
  if (d.status == JoinDecision::Status::kJoined) {
    const JoinPlan& p = PlanOf(s, d.winner);
    at.predicted_tested = p.predicted_tested;
    at.predicted_found = p.predicted_found;
    if (!p.failure.empty()) {
      d.status = JoinDecision::Status::kNoEvidence;
      d.reason = p.failure;
    }
    H = p.H;
    inliers = p.inliers;
  }
  at.status = d.status;
  at.reason = d.reason;
  at.winner = d.winner;
  at.rival = d.rival;
  at.frames = s.hypotheses;
  hooks_.info(JoinLog(at, s.seeds, s.places, s.candidates.size(), d));
  if (d.status != JoinDecision::Status::kJoined) {
    attempts_.push_back(at);
    return false;
  }
  at.T_A_B = H;
  JoinPlan applied;
  applied.H = H;
  applied.inliers = inliers;
  ApplyJoin(s, applied);
  stats_.join_rejected_loops += static_cast<int>(std::count(s.fine.begin(), s.fine.end(), 1) - inliers.size());
  ++stats_.joins;
  attempts_.push_back(at);
  return true;
}

// Every sequence of a joined part against the rest of its part, at the
// optimised poses: a join the loops later bent out of shape shows here.
void Slam::CheckFinalJoins() {
  const int anchor = AnchorComponent();
  std::map<std::string, int> joined_round;
  for (const auto& at : attempts_)
    if (at.status == JoinDecision::Status::kJoined) {
      std::stringstream names(at.b);
      for (std::string seq; std::getline(names, seq, '+');) joined_round.emplace(seq, at.round);
    }
  std::vector<std::string> sequences;
  for (const auto& kf : keyframes_)
    if (sequences.empty() || sequences.back() != kf.sequence) sequences.push_back(kf.sequence);
  const int64_t min_agreeing =
      std::max<int64_t>(1, std::llround(o_.join_min_overlap_m / FloorGridOptions{}.cell_m));
  sequence_joins_.clear();
  for (const std::string& seq : sequences) {
    SequenceJoin j;
    j.sequence = seq;
    const int c = component_.at(seq);
    j.component = NameOf(c).substr(0, NameOf(c).find('+'));
    if (seq == keyframes_.front().sequence)
      j.status = "anchor";
    else if (manual_.count(seq))
      j.status = "manual";
    else
      j.status = c == anchor ? "joined" : "separate";
    j.round = joined_round.count(seq) ? joined_round.at(seq) : 0;
    std::vector<const Keyframe*> own, rest;
    for (const auto& kf : keyframes_)
      if (component_.at(kf.sequence) == c) (kf.sequence == seq ? own : rest).push_back(&kf);
    if (!rest.empty()) {
      const FloorGrid fs = MakeFloor(own), fr = MakeFloor(rest);
      j.final_evidence = EvaluateJoin(fr, fs, Pose());
      j.consistent = !(j.final_evidence.Agreeing() >= min_agreeing &&
                       j.final_evidence.Conflict() > o_.join_max_conflict);
    }
    sequence_joins_.push_back(j);
  }
}

}  // namespace locforge::lidar

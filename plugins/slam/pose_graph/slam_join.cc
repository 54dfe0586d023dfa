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
  for (const Keyframe* k : kfs) g.AddScan(k->cloud, graph_.nodes.at(k->id));
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

// Joins part B to part A. Candidate loops: seeds (B's keyframes near its
// start against A's nearest keyframe under every turn about that start:
// sequences often start at one spot, heading unknown) and places (Scan
// Context over all keyframes). Each distinct frame they suggest is judged by
// the two maps' whole overlap; the winner's predicted loops along B are then
// tested, and B moves into A's frame with the loops that agree.
bool Slam::TryJoin(int A, int B, int round) {
  ++stats_.join_attempts;
  JoinAttempt at;
  at.round = round;
  at.a = NameOf(A);
  at.b = NameOf(B);
  const std::vector<const Keyframe*> ka = KeyframesOf(A), kb = KeyframesOf(B);
  auto nearest_a = [&](const Eigen::Vector3d& p) -> const Keyframe* {
    const Keyframe* best = nullptr;
    double best_d = o_.loop_radius_m;
    for (const Keyframe* a : ka) {
      const double d = (graph_.nodes.at(a->id).t - p).norm();
      if (d <= best_d) best_d = d, best = a;
    }
    return best;
  };
  // Loops between the parts: the rough step only, until a frame is chosen
  // (the overlap evidence needs no more); then the precise step for the
  // loops that agree with it.
  std::vector<JoinCandidate> candidates;
  std::vector<RegistrationResult> results;  // parallel: rough, or precise when `fine`
  std::vector<char> fine;
  std::set<std::pair<int, int>> tested;
  auto add = [&](const Keyframe& a, const Keyframe& b, const RegistrationResult& r, bool predicted, bool precise) {
    JoinCandidate c;
    c.a = a.id;
    c.b = b.id;
    c.T_A_B = graph_.nodes.at(a.id) * r.T_target_source * graph_.nodes.at(b.id).Inverse();
    c.p_b = graph_.nodes.at(b.id).t;
    c.overlap = r.inlier_fraction;
    c.predicted = predicted;
    candidates.push_back(c);
    results.push_back(r);
    fine.push_back(precise);
  };
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
  auto test = [&](const Keyframe& a, const Keyframe& b, const std::vector<Pose>& guesses) {
    tested.insert({a.id, b.id});
    ++stats_.join_tests;
    queued.push_back(RoughTask{&a, &b, guesses, {}});
  };
  auto run_queued = [&] {
    const LoopCheckOptions lo = LoopOptions(o_.join_rough_error);
    auto check = [&](RoughTask& t, const Registrar& registrar) {
      t.found = RoughCheck(registrar, *t.a, *t.b, t.guesses, lo);
    };
    if (!ForEachOnWorkers(queued.size(), [&](size_t n, size_t w) { check(queued[n], workers_[w].first); }, ""))
      for (RoughTask& t : queued) {
        hooks_.check_cancelled();
        check(t, registrar_);
      }
    for (const RoughTask& t : queued)
      for (const auto& r : t.found) add(*t.a, *t.b, r, false, false);
    queued.clear();
  };
  // Seeds: B's keyframes within join_seed_radius of its start p0, every
  // loop_stride-th, nearest first; for each turn H about p0, against the
  // keyframe of A nearest H p_b, from the guess T_ab = T_A_a^-1 H T_B_b.
  const Eigen::Vector3d p0 = graph_.nodes.at(kb.front()->id).t;
  std::vector<const Keyframe*> near_start;
  for (const Keyframe* b : kb)
    if ((graph_.nodes.at(b->id).t - p0).norm() <= o_.join_seed_radius_m) near_start.push_back(b);
  std::stable_sort(near_start.begin(), near_start.end(), [&](const Keyframe* x, const Keyframe* y) {
    return (graph_.nodes.at(x->id).t - p0).norm() < (graph_.nodes.at(y->id).t - p0).norm();
  });
  int seeds = 0;
  auto seed = [&](const std::vector<double>& yaws) {
    int n = 0;
    for (size_t i = 0; i < near_start.size() && n < o_.join_seeds; i += o_.loop_stride, ++n) {
      hooks_.check_cancelled();
      const Keyframe& b = *near_start[i];
      std::map<int, std::vector<Pose>> guesses;  // a -> guesses
      for (double yaw : yaws) {
        const Pose H = Pose(Eigen::Quaterniond::Identity(), p0) * YawPose(yaw) * Pose(Eigen::Quaterniond::Identity(), -p0);
        const Keyframe* a = nearest_a(H * graph_.nodes.at(b.id).t);
        if (a) guesses[a->id].push_back(graph_.nodes.at(a->id).Inverse() * H * graph_.nodes.at(b.id));
      }
      for (const auto& [a, g] : guesses) test(keyframes_[a], b, g);
    }
    seeds = std::max(seeds, n);
  };
  std::vector<double> turns;
  for (int h = 0; h < o_.loop_yaw_hypotheses; ++h) turns.push_back(2 * M_PI * h / o_.loop_yaw_hypotheses);
  seed(turns);
  // Places: for every loop_stride-th keyframe of B, A's keyframes nearest by
  // ring key, the best of them by Scan Context distance, checked from the
  // heading that distance found.
  int places = 0;
  for (size_t i = 0; i < kb.size(); i += o_.loop_stride) {
    hooks_.check_cancelled();
    const Keyframe& b = *kb[i];
    std::vector<std::pair<double, const Keyframe*>> ranked;
    for (const Keyframe* a : ka) ranked.emplace_back(RingKeyDistance(a->context, b.context), a);
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
      if (tested.count({a.id, b.id})) continue;
      test(a, b, {YawPose(matches[k].first.yaw)});
      ++places;
    }
  }
  run_queued();

  // Headings the places found, tried at the start too: a rough check starts
  // from the turns above, up to half a step off, and may not reach a heading
  // between them, while a place elsewhere in a floor of repeated rooms can
  // find the heading with the wrong translation.
  const double tolerance = o_.join_max_rotation_deg * M_PI / 180;
  auto near = [&](double yaw, auto begin, auto end) {
    return std::any_of(begin, end, [&](double k) { return std::abs(std::remainder(yaw - k, 2 * M_PI)) < tolerance; });
  };
  std::vector<double> yaws, place_yaws;
  for (const auto& c : candidates) yaws.push_back(YawOf(c.T_A_B));
  for (size_t i = 0; i < yaws.size(); ++i) {
    // A heading two loops agree on (one loop alone is as often noise), first time seen, not tried yet.
    const double y = yaws[i];
    if (!near(y, yaws.begin(), yaws.begin() + i) && near(y, yaws.begin() + i + 1, yaws.end()) &&
        !near(y, turns.begin(), turns.end()) && !near(y, place_yaws.begin(), place_yaws.end()))
      place_yaws.push_back(y);
  }
  seed(place_yaws);
  run_queued();

  // The frames suggested, judged by the whole overlap.
  JoinConsensusOptions agreement;
  agreement.max_translation = o_.join_max_translation_m;
  agreement.max_rotation_deg = o_.join_max_rotation_deg;
  std::vector<JoinHypothesis> hypotheses = ClusterHypotheses(candidates, agreement);
  const FloorGrid& fa = FloorOf(A);
  const FloorGrid& fb = FloorOf(B);
  for (auto& h : hypotheses) h.evidence = EvaluateJoin(fa, fb, h.T_A_B);
  const std::vector<Eigen::Vector3d> starts_a = SequenceStarts(ka), starts_b = SequenceStarts(kb);
  for (auto& h : hypotheses) h.start_offset_m = StartOffset(starts_a, starts_b, h.T_A_B);
  JoinDecisionOptions jo;
  jo.max_conflict = o_.join_max_conflict;
  jo.max_start_offset_m = o_.join_max_start_offset_m;
  jo.alias_conflict = std::max(o_.join_alias_conflict, o_.join_max_conflict);
  jo.alias_min_shift_m = o_.join_alias_min_shift_m;
  jo.alias_max_rotation_deg = o_.join_max_rotation_deg;
  jo.min_agreeing = std::max<int64_t>(1, std::llround(o_.join_min_overlap_m / fa.options().cell_m));
  jo.rival_conflict_ratio = o_.join_rival_conflict_ratio;
  jo.rival_conflict_margin = o_.join_rival_conflict_margin;
  jo.rival_overlap = o_.join_rival_overlap;
  jo.max_trials = o_.join_trials;
  jo.trial_max_conflict = o_.join_trial_max_conflict;
  JoinDecision d = DecideJoin(hypotheses, jo);
  at.candidates = static_cast<int>(candidates.size());
  at.hypotheses = static_cast<int>(hypotheses.size());

  // A frame's loops made precise, then the loops it predicts along B; the
  // precise loops agreeing with it, and the frame of the best-overlapping one.
  struct Plan {
    std::vector<int> inliers;
    Pose H;
    int predicted_tested = 0, predicted_found = 0;
    std::string failure;  // empty: its loops hold
  };
  std::map<int, Plan> plans;  // by hypothesis
  auto plan = [&](int w) -> const Plan& {
    if (plans.count(w)) return plans.at(w);
    Plan p;
    const JoinCandidate rep = candidates[hypotheses[w].loops.front()];
    for (int i : hypotheses[w].loops) {
      hooks_.check_cancelled();
      RegistrationResult precise;
      if (!FineCheck(registrar_, MakeRefiner(), keyframes_[candidates[i].a], keyframes_[candidates[i].b], results[i],
                     LoopOptions(o_.join_rough_error), &precise))
        continue;
      const Keyframe& a = keyframes_[candidates[i].a];
      const Keyframe& b = keyframes_[candidates[i].b];
      add(a, b, precise, false, true);
    }
    p.H = rep.T_A_B;
    std::vector<std::pair<const Keyframe*, const Keyframe*>> predicted;
    for (const Keyframe* b : kb) {
      const Keyframe* a = nearest_a(p.H * graph_.nodes.at(b->id).t);
      if (a && !tested.count({a->id, b->id})) predicted.emplace_back(a, b);
    }
    const size_t n = std::min<size_t>(predicted.size(), o_.join_verify);
    std::vector<int> mine;  // candidates this frame's verification found
    for (size_t k = 0; k < n; ++k) {
      hooks_.check_cancelled();
      const auto [a, b] = predicted[k * predicted.size() / n];
      tested.insert({a->id, b->id});
      ++stats_.join_tests;
      for (const auto& r : CheckLoop(*a, *b, {graph_.nodes.at(a->id).Inverse() * p.H * graph_.nodes.at(b->id)},
                                     o_.loop_rough_error))
        add(*a, *b, r, true, true);
    }
    std::set<int> support, verified;
    int best = -1;
    for (int i = 0; i < static_cast<int>(candidates.size()); ++i)
      if (fine[i] && HypothesesAgree(rep, candidates[i], agreement)) {
        p.inliers.push_back(i);
        support.insert(candidates[i].b);
        if (candidates[i].predicted) verified.insert(candidates[i].b);
        if (best < 0 || candidates[i].overlap > candidates[best].overlap) best = i;
      }
    if (best >= 0) p.H = candidates[best].T_A_B;
    p.predicted_tested = static_cast<int>(n);
    p.predicted_found = static_cast<int>(verified.size());
    if (static_cast<int>(support.size()) < o_.join_min_support ||
        static_cast<int>(verified.size()) < o_.join_min_verified)
      p.failure = "the frame explains the overlap but its loops do not hold: " + std::to_string(support.size()) +
                  " keyframes agree, " + std::to_string(verified.size()) + " of " + std::to_string(n) +
                  " predicted loops found";
    return plans.emplace(w, std::move(p)).first->second;
  };
  // B into A's frame by a plan (and its pre-optimisation copy, for the plot).
  auto apply = [&](const Plan& p) {
    for (const Keyframe* b : kb) {
      graph_.nodes[b->id] = p.H * graph_.nodes.at(b->id);
      before_.nodes[b->id] = p.H * before_.nodes.at(b->id);
    }
    for (int i : p.inliers) {
      const Keyframe& a = keyframes_[candidates[i].a];
      const Keyframe& b = keyframes_[candidates[i].b];
      if (!accepted_.count({std::min(a.id, b.id), std::max(a.id, b.id)})) AddLoopEdge(a, b, results[i]);
    }
    for (auto& [seq, c] : component_)
      if (c == B) c = A;
    ++poses_version_;
  };

  // Trials: no frame explains the overlap as the parts stand; the close ones
  // are joined on a copy of the state, optimised, and judged again.
  if (d.status != JoinDecision::Status::kJoined) {
    const std::vector<int> trials = TrialCandidates(hypotheses, jo);
    for (int w : trials) {
      const Plan& p = plan(w);
      if (!p.failure.empty()) continue;
      const PoseGraph graph = graph_, before = before_;
      const std::set<std::pair<int, int>> accepted = accepted_;
      const std::map<std::string, int> component = component_;
      const int version = poses_version_;
      const PoseGraphSummary summary = stats_.summary;
      apply(p);
      Optimize();
      hypotheses[w].tried = true;
      hypotheses[w].after = EvaluateJoin(MakeFloor(ka), MakeFloor(kb), Pose());
      graph_ = graph, before_ = before, accepted_ = accepted, component_ = component;
      poses_version_ = version, stats_.summary = summary;
      ++stats_.join_trials;
    }
    d = DecideAfterTrials(hypotheses, d, jo);
  }
  Pose H;
  std::vector<int> inliers;
  if (d.status == JoinDecision::Status::kJoined) {
    const Plan& p = plan(d.winner);
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
  std::ostringstream log;
  log << "pose_graph: join " << at.b << " to " << at.a << ": " << seeds << " seeds, " << places << " places, "
      << candidates.size() << " loops, " << hypotheses.size() << " frames";
  at.winner = d.winner;
  at.rival = d.rival;
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
  at.frames = hypotheses;
  if (at.predicted_tested > 0) log << "; predicted loops " << at.predicted_found << " of " << at.predicted_tested;
  log << ": " << (d.status == JoinDecision::Status::kJoined ? "joined" : "refused, " + d.reason);
  hooks_.info(log.str());

  if (d.status != JoinDecision::Status::kJoined) {
    attempts_.push_back(at);
    return false;
  }
  at.T_A_B = H;
  Plan applied;
  applied.H = H;
  applied.inliers = inliers;
  apply(applied);
  stats_.join_rejected_loops += static_cast<int>(std::count(fine.begin(), fine.end(), 1) - inliers.size());
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

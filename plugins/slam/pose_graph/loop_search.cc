#include "loop_search.h"

#include <limits>

namespace locforge::lidar {

std::vector<std::pair<int, int>> LoopCandidates(const std::vector<Keyframe>& keyframes,
                                                const std::map<int, Pose>& poses, const std::vector<int>& component,
                                                const LoopSearchOptions& o) {
  std::vector<std::pair<int, int>> out;
  const int stride = std::max(1, o.stride);
  for (size_t j = 0; j < keyframes.size(); j += stride) {
    const Keyframe& b = keyframes[j];
    const Eigen::Vector3d pb = poses.at(b.id).t;
    std::map<std::string, std::pair<double, int>> nearest;  // sequence -> (distance, keyframe)
    for (size_t i = 0; i < j; ++i) {
      const Keyframe& a = keyframes[i];
      if (a.sequence == b.sequence && b.travelled - a.travelled < o.min_travel_m) continue;
      if (component[i] != component[j]) continue;
      const double d = (poses.at(a.id).t - pb).norm();
      if (d > o.radius_m) continue;
      auto& best = nearest.emplace(a.sequence, std::make_pair(std::numeric_limits<double>::infinity(), -1)).first->second;
      if (d < best.first) best = {d, a.id};
    }
    for (const auto& [seq, best] : nearest) out.emplace_back(best.second, b.id);
  }
  return out;
}

std::vector<RegistrationResult> RoughCheck(const Registrar& registrar, const Keyframe& a, const Keyframe& b,
                                           const std::vector<Pose>& guesses, const LoopCheckOptions& o) {
  std::vector<RegistrationResult> roughs;
  for (const Pose& guess : guesses) {
    const RegistrationResult r = registrar(b.rough, a.rough, guess);
    if (!r.converged || r.final_error > o.rough_error_m || r.inlier_fraction < o.rough_overlap) continue;
    if ((r.T_target_source.t - guess.t).norm() > o.max_guess_distance_m) continue;
    bool same = false;
    for (auto& k : roughs)
      if ((k.T_target_source.t - r.T_target_source.t).norm() < 0.5 &&
          RotationAngleDeg(k.T_target_source.q, r.T_target_source.q) < 10) {
        if (r.inlier_fraction > k.inlier_fraction) k = r;
        same = true;
        break;
      }
    if (!same) roughs.push_back(r);
  }
  return roughs;
}

bool FineCheck(const Registrar& registrar, const Refiner& refine, const KeyframeCloud& cloud_of, const Keyframe& a,
               const Keyframe& b, const RegistrationResult& rough, const LoopCheckOptions& o,
               RegistrationResult* fine) {
  const std::shared_ptr<const Cloud> ca = cloud_of(a), cb = cloud_of(b);
  const RegistrationResult r = registrar(*cb, *ca, rough.T_target_source);
  if (!r.converged || r.inlier_fraction < o.overlap) return false;
  *fine = refine(r, *cb, *ca);
  return true;
}

std::vector<RegistrationResult> CheckLoop(const Registrar& registrar, const Refiner& refine,
                                          const KeyframeCloud& cloud_of, const Keyframe& a, const Keyframe& b,
                                          const std::vector<Pose>& guesses, const LoopCheckOptions& o) {
  std::vector<RegistrationResult> out;
  for (const auto& rough : RoughCheck(registrar, a, b, guesses, o)) {
    RegistrationResult fine;
    if (FineCheck(registrar, refine, cloud_of, a, b, rough, o, &fine)) out.push_back(fine);
  }
  return out;
}

}  // namespace locforge::lidar

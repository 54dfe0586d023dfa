// Loop closures of the LiDAR SLAM, coarse to fine (paper section 3.1):
// candidates by distance between estimated positions (and distance
// travelled, within one sequence), a rough registration of downsampled
// clouds with overlap and error thresholds, then the precise one.
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_LOOP_SEARCH_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_LOOP_SEARCH_H_

#include <functional>
#include <memory>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "keyframes.h"
#include "locforge/registration.h"

namespace locforge::lidar {

// A registration back-end as the SLAM uses it: source onto target from a guess of T_target_source.
using Registrar = std::function<RegistrationResult(const Cloud& source, const Cloud& target, const Pose& guess)>;

struct LoopSearchOptions {
  double radius_m = 4;          // between estimated positions of a candidate pair
  double min_travel_m = 8;      // travelled since a same-sequence candidate
  int stride = 2;               // candidates from every n-th keyframe
};

// Candidate pairs (a, b), a < b: for every stride-th keyframe b, the nearest
// keyframe a of every sequence (b's own included) within radius_m, in b's
// component, and for b's own sequence at least min_travel_m behind it.
// component[i]: the component of keyframe i (parts joined in one frame).
std::vector<std::pair<int, int>> LoopCandidates(const std::vector<Keyframe>& keyframes,
                                                const std::map<int, Pose>& poses, const std::vector<int>& component,
                                                const LoopSearchOptions& options);

struct LoopCheckOptions {
  double rough_overlap = 0.5;   // inlier fraction of the rough check
  double rough_error_m = 0.3;   // largest mean residual of the rough check
  double max_guess_distance_m = 4;  // a rough result farther from its guess is refused
  double overlap = 0.6;         // inlier fraction of the precise check
};

using Refiner = std::function<RegistrationResult(const RegistrationResult&, const Cloud&, const Cloud&)>;
// A keyframe's full cloud (kept in memory, or read when needed: Slam::CloudOf).
using KeyframeCloud = std::function<std::shared_ptr<const Cloud>(const Keyframe&)>;

// The coarse step of a loop check b -> a (T_ab): the rough registration
// (`rough` clouds) from each guess; the distinct solutions passing the
// thresholds (0.5 m, 10 deg apart), the best-overlapping of each.
std::vector<RegistrationResult> RoughCheck(const Registrar& registrar, const Keyframe& a, const Keyframe& b,
                                           const std::vector<Pose>& guesses, const LoopCheckOptions& options);
// The precise step from a rough solution (`cloud`), then `refine`; false
// when the precise registration fails its overlap.
bool FineCheck(const Registrar& registrar, const Refiner& refine, const KeyframeCloud& cloud_of, const Keyframe& a,
               const Keyframe& b, const RegistrationResult& rough, const LoopCheckOptions& options,
               RegistrationResult* fine);
// Both steps: the accepted precise results, at most one per distinct rough solution.
std::vector<RegistrationResult> CheckLoop(const Registrar& registrar, const Refiner& refine,
                                          const KeyframeCloud& cloud_of, const Keyframe& a, const Keyframe& b,
                                          const std::vector<Pose>& guesses, const LoopCheckOptions& options);

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_LOOP_SEARCH_H_

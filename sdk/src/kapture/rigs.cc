#include "locforge/kapture/rigs.h"

namespace locforge::kapture {

std::optional<Pose> DevicePose(const Trajectories& trajectories, const Rigs& rigs,
                               Timestamp timestamp, const std::string& device_id) {
  if (const Pose* own = trajectories.Find(timestamp, device_id)) return *own;
  const Rig* rig = rigs.RigOf(device_id);
  if (!rig) return std::nullopt;
  const TrajectoryKey key(timestamp, rig->id);
  const auto it = trajectories.poses.find(key);
  if (it == trajectories.poses.end()) return std::nullopt;
  const RigSensor* sensor = rig->Find(device_id);
  if (trajectories.PartsOf(key) != PoseParts::kComplete || sensor->parts != PoseParts::kComplete)
    return std::nullopt;
  return sensor->sensor_from_rig * it->second;  // T_sensor_world = T_sensor_rig * T_rig_world
}

Trajectories RigsRemove(const Trajectories& trajectories, const Rigs& rigs, bool keep_rig_poses) {
  Trajectories out;
  // Devices' own entries first, so a composed pose never overwrites one.
  for (const auto& [key, pose] : trajectories.poses) {
    // A partial rig pose cannot be composed: it stays as it is.
    if (rigs.Find(key.second) && !keep_rig_poses &&
        trajectories.PartsOf(key) == PoseParts::kComplete)
      continue;
    out.Set(key.first, key.second, pose, trajectories.PartsOf(key));
  }
  for (const auto& [key, rig_pose] : trajectories.poses) {
    const Rig* rig = rigs.Find(key.second);
    if (!rig) continue;
    if (trajectories.PartsOf(key) != PoseParts::kComplete) continue;
    for (const RigSensor& s : rig->sensors) {
      if (s.parts != PoseParts::kComplete) continue;
      if (out.Find(key.first, s.sensor_id)) continue;
      out.Set(key.first, s.sensor_id, s.sensor_from_rig * rig_pose);
    }
  }
  return out;
}

Trajectories RigsRecover(const Trajectories& trajectories, const Rigs& rigs,
                         bool keep_sensor_poses) {
  Trajectories out;
  for (const auto& [key, pose] : trajectories.poses) {
    const Rig* rig = rigs.RigOf(key.second);
    if (!rig || keep_sensor_poses) out.Set(key.first, key.second, pose, trajectories.PartsOf(key));
    if (!rig || out.Find(key.first, rig->id)) continue;
    // The first sensor of the rig (rigs.txt order) with a pose at this time.
    for (const RigSensor& s : rig->sensors) {
      const TrajectoryKey sk(key.first, s.sensor_id);
      const auto it = trajectories.poses.find(sk);
      if (it == trajectories.poses.end()) continue;
      if (s.parts != PoseParts::kComplete || trajectories.PartsOf(sk) != PoseParts::kComplete)
        continue;
      // T_rig_world = T_sensor_rig^-1 * T_sensor_world
      out.Set(key.first, rig->id, s.sensor_from_rig.Inverse() * it->second);
      break;
    }
  }
  return out;
}

}  // namespace locforge::kapture

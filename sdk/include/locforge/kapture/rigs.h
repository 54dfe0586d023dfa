// Rigs and trajectories: per-sensor poses from rig poses and back, with the
// toolbox's convention (kapture/algo/... rigs_remove / rigs_recover):
//
//   T_sensor_world = T_sensor_rig * T_rig_world
//
// where T_rig_world is the rig's trajectory entry and T_sensor_rig the
// rigs.txt entry (checked on virtual_gallery_metadata, whose training split
// has both the rig extrinsics and the per-camera poses).
#ifndef LOCFORGE_KAPTURE_RIGS_H_
#define LOCFORGE_KAPTURE_RIGS_H_

#include <optional>
#include <string>

#include "locforge/kapture/types.h"

namespace locforge::kapture {

// The pose of `device_id` at `timestamp`: its own trajectory entry if any,
// else the composition with the trajectory entry of the rig holding it.
// Partial poses (rotation- or translation-only, or neither, like t265's
// empty rig poses) are not composed: the toolbox's PoseTransform.compose
// asserts both parts too.
std::optional<Pose> DevicePose(const Trajectories& trajectories, const Rigs& rigs,
                               Timestamp timestamp, const std::string& device_id);

// Replaces every rig trajectory entry by one entry per sensor of the rig
// (T_sensor_rig * T_rig_world). Entries of devices that are not rigs are
// kept. `keep_rig_poses` keeps the rig entries as well. A sensor entry that
// already exists at that timestamp is kept as it was (not overwritten).
Trajectories RigsRemove(const Trajectories& trajectories, const Rigs& rigs,
                        bool keep_rig_poses = false);

// The inverse: for each timestamp where sensors of a rig have poses, the
// rig pose T_rig_world = T_sensor_rig^-1 * T_sensor_world from the first of
// the rig's sensors (rigs.txt order) present; the sensor entries of rigs are
// removed unless `keep_sensor_poses`. Devices outside rigs are kept.
Trajectories RigsRecover(const Trajectories& trajectories, const Rigs& rigs,
                         bool keep_sensor_poses = false);

}  // namespace locforge::kapture

#endif  // LOCFORGE_KAPTURE_RIGS_H_

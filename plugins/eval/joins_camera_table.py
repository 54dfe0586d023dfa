#!/usr/bin/python3
"""Camera poses of a lidar_sweep workspace run with images (--set cameras=true): per seed, the rig
and camera errors after one rigid alignment of the whole recording (joins/summary.json), beside
the rotation error the cameras' unsynchronised clocks alone put into poses taken at their
timestamps: RMS yaw rate of the true rig trajectory x RMS of (clock offset, jitter) from the
recording's truth/calibration.yaml. Usage: joins_camera_table.py WORKSPACE"""
import glob, json, math, os, re, sys


def clock_floor_deg(recording):
    yaw = {}
    for line in open(os.path.join(recording, "sensors", "trajectories.txt")):
        if line.startswith("#"):
            continue
        f = [x.strip() for x in line.split(",")]
        if len(f) < 9 or f[1] != "rig":
            continue
        qw, qx, qy, qz = map(float, f[2:6])
        # T_rig_world: the rig's heading in the world is that of its inverse (transposed rotation).
        r10 = 2 * (qx * qy - qz * qw)
        r00 = 1 - 2 * (qy * qy + qz * qz)
        yaw[int(f[0])] = math.atan2(r10, r00)
    ts = sorted(yaw)
    rates = [math.remainder(yaw[b] - yaw[a], 2 * math.pi) / ((b - a) * 1e-6)
             for a, b in zip(ts, ts[1:]) if 0 < (b - a) * 1e-6 < 0.2]
    text = open(os.path.join(recording, "truth", "calibration.yaml")).read()
    offsets = [float(x) for x in re.findall(r"clock_offset_s: ([-0-9.e]+)", text)]
    jitter = [float(x) for x in re.findall(r"jitter_s: ([-0-9.e]+)", text)]
    if not rates or not offsets:
        return float("nan")
    sigma = math.sqrt(sum(o * o for o in offsets) / len(offsets) + (sum(j * j for j in jitter) / len(jitter) if jitter else 0))
    return math.degrees(math.sqrt(sum(r * r for r in rates) / len(rates))) * sigma


def main():
    w = sys.argv[1]
    print("| seed | rig: ATE (cm) / rotation (deg) | cameras: ATE (cm) / rotation (deg) | clocks alone (deg) | sqrt(rig^2 + clocks^2) (deg) |")
    print("|---|---|---|---|---|")
    for v in sorted(glob.glob(os.path.join(w, "variants", "seed=*")), key=lambda p: int(p.split("=")[-1])):
        summary = os.path.join(v, "nodes", "joins", "summary.json")
        if not os.path.exists(summary):
            continue  # not run (yet)
        s = json.load(open(summary))
        floor = clock_floor_deg(os.path.realpath(os.path.join(v, "nodes", "recording")))
        rig_rot = s["rotation_whole_deg"]
        print("| %s | %.2f / %.3f | %.2f / %.3f | %.3f | %.3f |" % (
            v.split("=")[-1], 100 * s["ate_whole_m"], rig_rot, 100 * s.get("camera_ate_whole_m", float("nan")),
            s.get("camera_rotation_whole_deg", float("nan")), floor, math.hypot(rig_rot, floor)))


if __name__ == "__main__":
    main()

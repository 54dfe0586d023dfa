#!/usr/bin/python3
"""Camera poses of both ground-truth halves over a configs/gt/camera_sweep.yaml workspace, per seed:
the rig and camera poses of the LiDAR half (joins/summary.json: one rigid alignment of the whole
recording on the rig poses) and the camera poses before and after the SfM half (cameras/calibration.csv:
one SE(3) alignment of all camera poses of the recording per estimate), with the bundle adjustment's
camera rotations (extrinsics), focal errors and the gt node's wall seconds. Usage: camera_sweep_table.py WORKSPACE"""
import csv, glob, json, os, sys


def rows_of(path):
    with open(path, newline="") as f:
        return {r["estimate"]: r for r in csv.DictReader(f)}


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    w = sys.argv[1]
    print("| seed | images | rig: ATE (cm) / rotation (deg) | LiDAR half cameras (cm / deg) | "
          "SfM half cameras (cm / deg) | camera rotations (extrinsics) RMS / max (deg) | focal RMS (%) | gt node s |")
    print("|---|---|---|---|---|---|---|---|")
    for v in sorted(glob.glob(os.path.join(w, "variants", "seed=*")), key=lambda p: int(p.split("=")[-1])):
        summary = os.path.join(v, "nodes", "joins", "summary.json")
        calibration = os.path.join(v, "nodes", "cameras", "calibration.csv")
        if not os.path.exists(summary) or not os.path.exists(calibration):
            continue  # not run (yet)
        s = json.load(open(summary))
        c = rows_of(calibration)
        if "lidar_half" not in c or "spline_ba" not in c:
            sys.exit("%s: no 'lidar_half' and 'spline_ba' rows (eval/calibration labels of camera_sweep.yaml)" % calibration)
        lidar, ba = c["lidar_half"], c["spline_ba"]
        seconds = "-"
        manifest = os.path.join(v, "nodes", "gt", ".locforge-complete")  # its wall time: triangulation + BA
        if os.path.exists(manifest):
            seconds = "%.0f" % json.load(open(manifest)).get("seconds", float("nan"))
        print("| %s | %s | %.2f / %.3f | %s / %s | %s / %s | %s / %s | %s | %s |" % (
            v.split("=")[-1], ba["images"], 100 * s["ate_whole_m"], s["rotation_whole_deg"],
            lidar["position RMS (cm)"], lidar["rotation RMS (deg)"], ba["position RMS (cm)"],
            ba["rotation RMS (deg)"], ba["camera rotation RMS (deg)"], ba["camera rotation max (deg)"],
            ba["focal error RMS (%)"], seconds))


if __name__ == "__main__":
    main()

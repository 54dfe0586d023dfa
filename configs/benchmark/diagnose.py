#!/usr/bin/env python3
"""Where a localization run loses its queries, stage by stage, from the ground truth.

For a finished sift_densevlad.yaml-style workspace (nodes map, query, query_pairs,
query_verified, triangulation, pnp, eval_pnp) and the query kapture with its true
poses, prints one line per query and a summary:

  retrieval   retrieved map images / those that truly see the query's scene (>= 20 of
              their map points project into the query at its true pose)
  matches     verified query-to-map matches, summed over the retrieved pairs
  2d-3d       unique (query keypoint, map point) correspondences, and how many are
              right at the true pose (reprojection error <= --max-error-px)
  pose        inliers of the estimated pose, position / rotation error
and the map: points, observations per map image, track length, triangulation angle.

  python3 configs/benchmark/diagnose.py W [--query DIR] [--max-error-px 12]

Needs numpy (Debian: python3-numpy). PINHOLE / SIMPLE_PINHOLE query cameras.
"""
import argparse
import collections
import csv
import math
import sys
from pathlib import Path

import numpy as np


def rows(path):
    with open(path) as f:
        for line in f:
            if line.strip() and not line.startswith("#"):
                yield [x.strip() for x in line.split(",")]


def rotation(qw, qx, qy, qz):
    w, x, y, z = qw, qx, qy, qz
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def load_kapture(root):
    """image -> (K, width, height, R, t) for every camera record with a pose."""
    sensors = {}
    for r in rows(root / "sensors/sensors.txt"):
        if r[2] != "camera":
            continue
        model, p = r[3], [float(v) for v in r[4:]]
        if model == "PINHOLE":
            w, h, fx, fy, cx, cy = p[:6]
        elif model == "SIMPLE_PINHOLE":
            w, h, fx, cx, cy = p[:5]
            fy = fx
        else:
            sys.exit(f"{root}/sensors/sensors.txt: camera model {model} not handled here")
        sensors[r[0]] = (np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]]), w, h)
    poses = {}
    for r in rows(root / "sensors/trajectories.txt"):
        poses[(r[0], r[1])] = (rotation(*map(float, r[2:6])), np.array(list(map(float, r[6:9]))))
    out = {}
    for r in rows(root / "sensors/records_camera.txt"):
        if r[1] in sensors and (r[0], r[1]) in poses:
            K, w, h = sensors[r[1]]
            R, t = poses[(r[0], r[1])]
            out[r[2]] = (K, w, h, R, t)
    return out


def keypoints(folder, image):
    for kind in sorted((folder / "reconstruction/keypoints").iterdir()):
        f = kind / (image + ".kpt")
        if f.exists():
            dsize = int(list(rows(kind / "keypoints.txt"))[0][2])
            return np.fromfile(f, dtype=np.float32).reshape(-1, dsize)[:, :2].astype(np.float64)
    return np.zeros((0, 2))


def matches(folder, a, b):
    """Matches of the pair as (index in a, index in b)."""
    for kind in (folder / "reconstruction/matches").iterdir():
        for x, y, flip in ((a, b, False), (b, a, True)):
            f = kind / (x + ".overlapping") / (y + ".matches")
            if f.exists():
                m = np.fromfile(f, dtype=np.float64).reshape(-1, 3)[:, :2].astype(np.int64)
                return m[:, ::-1] if flip else m
    return np.zeros((0, 2), dtype=np.int64)


class NodeFolders:
    """workspace/nodes/PREFIX+name for n / "name/..." paths."""
    def __init__(self, nodes, prefix):
        self.nodes, self.prefix = nodes, prefix

    def __truediv__(self, rest):
        return self.nodes / (self.prefix + rest)


def project(K, R, t, X):
    c = X @ R.T + t
    z = c[:, 2]
    uv = (c @ K.T)[:, :2] / np.where(np.abs(z) < 1e-12, 1e-12, z)[:, None]
    return uv, z


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("workspace", type=Path)
    p.add_argument("--query", type=Path, help="query kapture with true poses (default: the query node)")
    p.add_argument("--max-error-px", type=float, default=12.0)
    p.add_argument("--csv", type=Path, help="write the per-query table here too")
    p.add_argument("--prefix", default="", help="prefix of the graph's node names (the demo's: bench_)")
    a = p.parse_args()
    n = NodeFolders(a.workspace / "nodes", a.prefix)
    truth = load_kapture(a.query or n / "query")
    mapk = load_kapture(n / "map")
    points = np.array([[float(v) for v in r[:3]] for r in rows(n / "triangulation/reconstruction/points3d.txt")])
    observed = collections.defaultdict(dict)  # map image -> feature -> point ids
    track = []
    for r in rows(n / "triangulation/reconstruction/observations.txt"):
        pid = int(r[0])
        ims = r[2::2]
        track.append(len(set(ims)))
        for im, f in zip(r[2::2], r[3::2]):
            observed[im].setdefault(int(f), []).append(pid)
    # Map summary: points, observations per image, track length, triangulation angle.
    angles = []
    centres = {im: -R.T @ t for im, (K, w, h, R, t) in mapk.items()}
    for r in rows(n / "triangulation/reconstruction/observations.txt"):
        X = points[int(r[0])]
        rays = [centres[im] - X for im in set(r[2::2]) if im in centres]
        best = 0.0
        for i in range(len(rays)):
            for j in range(i + 1, len(rays)):
                c = rays[i] @ rays[j] / (np.linalg.norm(rays[i]) * np.linalg.norm(rays[j]) + 1e-12)
                best = max(best, math.degrees(math.acos(max(-1, min(1, c)))))
        angles.append(best)
    per_image = [sum(len(v) for v in observed[im].values()) for im in mapk]
    print(f"map: {len(mapk)} images, {len(points)} points, observations per image median "
          f"{np.median(per_image):.0f} (min {min(per_image)}, {sum(1 for x in per_image if x < 50)} images < 50), "
          f"track length mean {np.mean(track):.2f}, triangulation angle median {np.median(angles):.1f} deg")

    pairs = collections.defaultdict(list)
    for r in rows(n / "query_pairs/pairs.txt"):
        pairs[r[0]].append(r[1])
    stats = {r["item"]: r for r in csv.DictReader(open(n / "pnp/localization_stats.csv"))}
    errors = {r["image"]: r for r in csv.DictReader(open(n / "eval_pnp/per_query.csv"))}
    table = []
    for q in sorted(truth):
        K, w, h, R, t = truth[q]
        # Retrieval: map images that truly see the query's scene.
        sees = set()
        for im, feats in observed.items():
            ids = sorted({pid for v in feats.values() for pid in v})
            if not ids:
                continue
            uv, z = project(K, R, t, points[ids])
            inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
            if inside.sum() >= 20:
                sees.add(im)
        retrieved = set(pairs.get(q, []))
        kq = keypoints(n / "query_features", q)
        verified = 0
        corr = set()
        for im in retrieved:
            m = matches(n / "query_verified", q, im)
            verified += len(m)
            for iq, imap in m:
                for pid in observed.get(im, {}).get(int(imap), []):
                    corr.add((int(iq), pid))
        right = 0
        if corr:
            c = np.array(sorted(corr))
            uv, z = project(K, R, t, points[c[:, 1]])
            err = np.linalg.norm(uv - kq[c[:, 0]], axis=1)  # both: first pixel centre at (0.5, 0.5)
            right = int(np.sum((z > 0) & (err <= a.max_error_px)))
        s, e = stats.get(q, {}), errors.get(q, {})
        table.append(dict(query=q, retrieved=len(retrieved), seeing=len(sees), hit=len(retrieved & sees),
                          verified=verified, corr=len(corr), right=right, inliers=s.get("inliers", ""),
                          status=s.get("status", ""),
                          pos=e.get("position_error_m", ""), rot=e.get("rotation_error_deg", "")))
    cols = ["query", "retrieved", "seeing", "hit", "verified", "corr", "right", "inliers", "status", "pos", "rot"]
    print("  ".join(f"{c:>10}" for c in cols))
    for r in table:
        pos = f"{float(r['pos']):.4f}" if r["pos"] else "-"
        rot = f"{float(r['rot']):.3f}" if r["rot"] else "-"
        print("  ".join(f"{v:>10}" for v in [r["query"][-10:], r["retrieved"], r["seeing"], r["hit"], r["verified"],
                                             r["corr"], r["right"], r["inliers"], r["status"], pos, rot]))
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            wr = csv.DictWriter(f, fieldnames=cols)
            wr.writeheader()
            wr.writerows(table)
    ok = [r for r in table if r["pos"] and float(r["pos"]) <= 0.1 and float(r["rot"]) <= 1]
    print(f"queries {len(table)}: within (0.1 m, 1 deg) {len(ok)}; retrieval missed a seeing map image for "
          f"{sum(1 for r in table if r['hit'] < r['seeing'])}; median right 2D-3D {np.median([r['right'] for r in table]):.0f} "
          f"of {np.median([r['corr'] for r in table]):.0f}")


if __name__ == "__main__":
    main()

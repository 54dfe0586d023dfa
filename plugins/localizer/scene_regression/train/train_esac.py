#!/usr/bin/env python3
"""Trains ESAC (Brachmann and Rother, ICCV 2019) on a kapture map with depth
records and exports the ONNX models that localizer/esac runs (contract:
../README.md): DIR/expert_000.onnx ... and, with several experts, DIR/gating.onnx.

  python3 train_esac.py --map MAP_KAPTURE --depth DEPTH_KAPTURE --experts 10 --out DIR

Scene coordinates: each network output cell (stride 8) stands for the pixel at
its centre; its target is that pixel's depth (records_depth.txt, e.g.
gt/lidar_depth's LiDAR depth) unprojected with the camera and moved to the map
frame with the image's pose. Experts: k-means (k-means++ seeding) on the map's
scene coordinates, as ESAC splits a scene into regions; an image belongs to
the cluster holding most of its coordinates; expert e is trained on its images
(L1 on the cells with depth, targets centred and scaled per cluster, the
export adds them back); the gating network is a classifier of the image's
cluster (cross-entropy). ESAC's end-to-end stage (through differentiable
RANSAC) is not run: the CPU budget. Writes DIR/training.json.
"""
import argparse
import os
import platform
import sys
import time

import numpy as np
import torch
import torch.nn as nn

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import kapture_io  # noqa: E402
from nets import Gating, SceneCoordinates, atomic_export, atomic_json, augment  # noqa: E402


def scene_coordinates(camera, T_camera_world, depth, h, w):
    """h x w x 3 world coordinates at the cell centres (NaN without depth)."""
    j, i = np.meshgrid(np.arange(w), np.arange(h))
    u = (j + 0.5) * camera.width / w
    v = (i + 0.5) * camera.height / h
    z = depth[np.minimum(v.astype(int), depth.shape[0] - 1), np.minimum(u.astype(int), depth.shape[1] - 1)]
    p_cam = camera.unproject(u, v) * z[..., None]
    R, t = T_camera_world[:3, :3], T_camera_world[:3, 3]
    world = (p_cam - t) @ R  # R^T (p - t)
    world[z <= 0] = np.nan
    return world


def kmeans(points, k, seed, iterations=30):
    rng = np.random.default_rng(seed)
    centres = [points[rng.integers(len(points))]]
    for _ in range(1, k):  # k-means++
        d = np.min(((points[:, None, :] - np.array(centres)[None]) ** 2).sum(-1), axis=1)
        centres.append(points[rng.choice(len(points), p=d / d.sum())])
    centres = np.array(centres)
    for _ in range(iterations):
        label = np.argmin(((points[:, None, :] - centres[None]) ** 2).sum(-1), axis=1)
        for c in range(k):
            if np.any(label == c):
                centres[c] = points[label == c].mean(axis=0)
    return centres


def nearest(points, centres):
    return np.argmin(((points[:, None, :] - centres[None]) ** 2).sum(-1), axis=1)


def train_expert(X, Y, centre, scale, iterations, batch, lr, log):
    """L1 on the cells with a target; returns the net and the final mean error (m)."""
    net = SceneCoordinates()
    opt = torch.optim.Adam(net.parameters(), lr=lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, iterations)
    Xt = torch.from_numpy(X)
    Yt = torch.from_numpy((Y - centre.reshape(1, 3, 1, 1)) / scale).float()
    valid = ~torch.isnan(Yt[:, :1])
    Yt = torch.nan_to_num(Yt)
    err = float("nan")
    for it in range(iterations):
        net.train()
        idx = torch.randint(len(Xt), (min(batch, len(Xt)),))
        pred = net(augment(Xt[idx]))
        m = valid[idx].float()
        dist = (pred - Yt[idx]).norm(dim=1, keepdim=True)
        loss = (dist * m).sum() / m.sum().clamp_min(1)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        err = float(loss) * scale
        if (it + 1) % max(1, iterations // 5) == 0:
            log(f"  iteration {it + 1}/{iterations}: mean coordinate error {err:.2f} m")
    net.eval()
    return net, err


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--map", required=True, help="kapture with poses (the training images)")
    ap.add_argument("--depth", required=True, help="kapture with records_depth.txt for those images")
    ap.add_argument("--images", default="", help="regex on image paths: train only on these")
    ap.add_argument("--experts", type=int, default=1)
    ap.add_argument("--out", required=True, help="output folder")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=128)
    ap.add_argument("--iterations", type=int, default=4000, help="training iterations of the single expert")
    ap.add_argument("--expert-iterations", type=int, default=1000, help="iterations per expert when experts > 1")
    ap.add_argument("--gating-epochs", type=int, default=40)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    if a.width % 8 or a.height % 8:
        sys.exit("--width and --height must be multiples of 8 (the experts' stride)")
    torch.manual_seed(a.seed)
    torch.set_num_threads(a.threads)
    start = time.time()
    log = lambda s: print(s, flush=True)  # noqa: E731

    k = kapture_io.Kapture(a.map)
    depth_files = kapture_io.read_depth_records(a.depth)
    h, w = a.height // SceneCoordinates.STRIDE, a.width // SceneCoordinates.STRIDE
    X, Y, names = [], [], []
    skipped = 0
    for t, cam, path, T in k.posed_images(a.images):
        file = depth_files.get((t, cam))
        if file is None or not os.path.exists(file):
            skipped += 1
            continue
        camera = k.cameras[cam]
        depth = kapture_io.read_depth(file, camera.width, camera.height)
        X.append(kapture_io.normalise(kapture_io.load_image(k.image_file(path), a.width, a.height)))
        Y.append(scene_coordinates(camera, T, depth, h, w).transpose(2, 0, 1))
        names.append(path)
    if not X:
        sys.exit(f"{a.map}: no posed image with a depth record in {a.depth}")
    X, Y = np.stack(X), np.stack(Y).astype(np.float32)
    load_seconds = time.time() - start
    valid_share = float(np.mean(~np.isnan(Y[:, 0])))
    log(f"{len(X)} images with depth ({skipped} without), {valid_share:.0%} of the cells with a target, "
        f"loaded in {load_seconds:.0f} s")

    # Experts: k-means on the scene coordinates; each image to its majority cluster.
    points = Y.transpose(0, 2, 3, 1).reshape(-1, 3)
    points = points[~np.isnan(points[:, 0])]
    rng = np.random.default_rng(a.seed)
    sample = points[rng.choice(len(points), min(len(points), 20000), replace=False)]
    centres = kmeans(sample, a.experts, a.seed) if a.experts > 1 else sample.mean(axis=0, keepdims=True)
    labels = np.zeros(len(X), int)
    for n in range(len(X)):
        p = Y[n].reshape(3, -1).T
        p = p[~np.isnan(p[:, 0])]
        labels[n] = np.bincount(nearest(p, centres), minlength=a.experts).argmax() if len(p) else 0
    os.makedirs(a.out, exist_ok=True)
    experts = []
    for e in range(a.experts):
        mine = np.flatnonzero(labels == e)
        if len(mine) == 0:  # a cluster no image is mostly in: the images that see most of it
            counts = [np.sum(nearest(Y[n].reshape(3, -1).T[~np.isnan(Y[n, 0].ravel())], centres) == e)
                      for n in range(len(X))]
            mine = np.argsort(counts)[-5:]
        p = Y[mine].transpose(0, 2, 3, 1).reshape(-1, 3)
        p = p[~np.isnan(p[:, 0])]
        centre = p.mean(axis=0)
        scale = float(np.sqrt(((p - centre) ** 2).sum(-1).mean())) or 1.0
        iterations = a.iterations if a.experts == 1 else a.expert_iterations
        log(f"expert {e}: {len(mine)} images, centre {centre.round(1)}, scale {scale:.1f} m")
        t0 = time.time()
        net, err = train_expert(X[mine], Y[mine], centre, scale, iterations, a.batch, a.lr, log)
        file = os.path.join(a.out, f"expert_{e:03d}.onnx")
        atomic_export(SceneCoordinates.Exported(net, centre, scale), torch.zeros(1, 3, a.height, a.width), file,
                      ["coordinates"])
        experts.append({"expert": e, "images": int(len(mine)), "centre": centre.tolist(), "scale_m": scale,
                        "iterations": iterations, "final_train_error_m": err, "seconds": round(time.time() - t0, 1),
                        "model_bytes": os.path.getsize(file)})

    gating = None
    if a.experts > 1:
        t0 = time.time()
        net = Gating(a.experts)
        opt = torch.optim.Adam(net.parameters(), lr=a.lr)
        Xt, Lt = torch.from_numpy(X), torch.from_numpy(labels)
        for epoch in range(a.gating_epochs):
            net.train()
            order = torch.randperm(len(Xt))
            correct = 0
            for b in range(0, len(Xt), 16):
                idx = order[b:b + 16]
                logits = net(augment(Xt[idx]))
                loss = nn.functional.cross_entropy(logits, Lt[idx])
                opt.zero_grad()
                loss.backward()
                opt.step()
                correct += int((logits.argmax(1) == Lt[idx]).sum())
            if (epoch + 1) % max(1, a.gating_epochs // 5) == 0:
                log(f"gating epoch {epoch + 1}/{a.gating_epochs}: train accuracy {correct / len(Xt):.0%}")
        file = os.path.join(a.out, "gating.onnx")
        atomic_export(net, torch.zeros(1, 3, a.height, a.width), file, ["logits"])
        gating = {"epochs": a.gating_epochs, "train_accuracy": correct / len(Xt), "seconds": round(time.time() - t0, 1),
                  "model_bytes": os.path.getsize(file)}

    total = time.time() - start
    record = {
        "recipe": "plugins/localizer/scene_regression/train/train_esac.py", "argv": sys.argv[1:],
        "map": os.path.abspath(a.map), "depth": os.path.abspath(a.depth), "images": len(X),
        "images_without_depth": skipped, "cells_with_target": valid_share, "experts": experts, "gating": gating,
        "width": a.width, "height": a.height, "batch": a.batch, "lr": a.lr, "threads": a.threads, "seed": a.seed,
        "load_seconds": round(load_seconds, 1), "train_seconds": round(total, 1),
        "model_bytes": sum(x["model_bytes"] for x in experts) + (gating["model_bytes"] if gating else 0),
        "torch": torch.__version__, "machine": platform.machine(), "cpus": os.cpu_count(),
    }
    atomic_json(os.path.join(a.out, "training.json"), record)
    log(f"wrote {a.experts} expert(s){' + gating' if gating else ''} to {a.out} in {total:.0f} s")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Trains a PoseNet-style absolute pose regressor on a kapture map and exports
the ONNX model that localizer/posenet runs (contract: ../README.md).

  python3 train_posenet.py --map MAP_KAPTURE --out DIR [--epochs 150] [--width 160 --height 128]

CPU only (Debian's python3-torch). The network is a small CNN (five strided
3x3 convolutions with batch norm, global average pooling, two linear heads),
not GoogLeNet: the CPU budget of the benchmark. Loss: Kendall and Cipolla's
learnt homoscedastic weighting (CVPR 2017) of |c - c^| and |q - q^/|q^||,
positions centred and scaled by the map's extent (the export adds them back,
so the ONNX outputs are in the map's frame and metres).
Writes DIR/posenet.onnx and DIR/training.json (data, settings, time, losses).
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
from nets import PoseNet, atomic_export, atomic_json, augment  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--map", required=True, help="kapture with poses (the training images)")
    ap.add_argument("--images", default="", help="regex on image paths: train only on these")
    ap.add_argument("--out", required=True, help="output folder (posenet.onnx, training.json)")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=128)
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    torch.manual_seed(a.seed)
    np.random.seed(a.seed)
    torch.set_num_threads(a.threads)
    start = time.time()

    k = kapture_io.Kapture(a.map)
    images = k.posed_images(a.images)
    if not images:
        sys.exit(f"{a.map}: no posed images" + (f" matching {a.images}" if a.images else ""))
    x = np.stack([kapture_io.normalise(kapture_io.load_image(k.image_file(p), a.width, a.height))
                  for _, _, p, _ in images])
    centres, quats = [], []
    for _, _, _, T in images:
        R = T[:3, :3].T  # world_from_camera
        centres.append(-R @ T[:3, 3])
        quats.append(kapture_io.matrix_to_quat(R))
    centres, quats = np.array(centres), np.array(quats)
    mean = centres.mean(axis=0)
    scale = float(np.abs(centres - mean).max()) or 1.0
    load_seconds = time.time() - start
    print(f"{len(images)} images loaded in {load_seconds:.1f} s; positions centred on {mean.round(2)}, scale {scale:.2f} m",
          flush=True)

    net = PoseNet()
    log_sx = nn.Parameter(torch.tensor(0.0))
    log_sq = nn.Parameter(torch.tensor(-3.0))
    opt = torch.optim.Adam(list(net.parameters()) + [log_sx, log_sq], lr=a.lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, a.epochs)
    X = torch.from_numpy(x)
    C = torch.from_numpy((centres - mean) / scale).float()
    Q = torch.from_numpy(quats).float()
    history = []
    for epoch in range(a.epochs):
        net.train()
        order = torch.randperm(len(X))
        total, pos_err, rot_err = 0.0, 0.0, 0.0
        for b in range(0, len(X), a.batch):
            idx = order[b:b + a.batch]
            c, q = net(augment(X[idx]))
            qn = q / q.norm(dim=1, keepdim=True).clamp_min(1e-8)
            lc = (c - C[idx]).norm(dim=1).mean()
            lq = torch.minimum((qn - Q[idx]).norm(dim=1), (qn + Q[idx]).norm(dim=1)).mean()
            loss = lc * torch.exp(-log_sx) + log_sx + lq * torch.exp(-log_sq) + log_sq
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += float(loss) * len(idx)
            pos_err += float(lc) * len(idx) * scale
            rot_err += float(lq) * len(idx)
        sched.step()
        n = len(X)
        history.append({"epoch": epoch + 1, "loss": total / n, "position_m": pos_err / n, "quaternion_l2": rot_err / n})
        print(f"epoch {epoch + 1}/{a.epochs}: loss {total / n:.3f}, train position {pos_err / n:.2f} m, "
              f"quaternion {rot_err / n:.3f}", flush=True)

    train_seconds = time.time() - start
    net.eval()
    exported = PoseNet.Exported(net, mean, scale)
    os.makedirs(a.out, exist_ok=True)
    onnx_file = os.path.join(a.out, "posenet.onnx")
    atomic_export(exported, torch.zeros(1, 3, a.height, a.width), onnx_file, ["position", "orientation"])
    record = {
        "recipe": "plugins/localizer/scene_regression/train/train_posenet.py", "argv": sys.argv[1:],
        "map": os.path.abspath(a.map), "images": len(images), "width": a.width, "height": a.height,
        "epochs": a.epochs, "batch": a.batch, "lr": a.lr, "threads": a.threads, "seed": a.seed,
        "position_mean": mean.tolist(), "position_scale": scale,
        "load_seconds": round(load_seconds, 1), "train_seconds": round(train_seconds, 1),
        "model_bytes": os.path.getsize(onnx_file), "parameters": sum(p.numel() for p in net.parameters()),
        "torch": torch.__version__, "machine": platform.machine(), "cpus": os.cpu_count(),
        "final": history[-1], "history": history,
    }
    atomic_json(os.path.join(a.out, "training.json"), record)
    print(f"wrote {onnx_file} ({record['model_bytes']} bytes), trained in {train_seconds:.0f} s")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Trains a small person-segmentation network on a simulator recording's
mapping images and true person masks, and exports the ONNX model that
analysis/person_segmentation runs (contract: plugins/analysis/README.md).

  python3 train_person_segmentation.py --recording REC [REC ...] --out DIR

Masks are read at REC/truth/masks/mapping/<image path>.png (255 on people).
Several recordings (e.g. a sparse and a dense crowd) teach both empty and
crowded views: one crowd density alone biases the masks toward it.
Network: three stride-2/1 blocks and two dilated blocks (stride 4 output),
a 1x1 convolution to one logit, the sigmoid folded into the export; loss:
binary cross-entropy against each 4x4 cell's person fraction; brightness and
contrast jitter. Writes DIR/person_segmentation.onnx and DIR/training.json.
"""
import argparse
import os
import platform
import sys
import time

import numpy as np
import torch
import torch.nn as nn
from PIL import Image

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import kapture_io  # noqa: E402
from nets import atomic_export, atomic_json, augment, block  # noqa: E402

STRIDE = 4


class PersonSegmentation(nn.Module):
    def __init__(self):
        super().__init__()
        self.body = nn.Sequential(block(3, 32, 2), block(32, 64, 2), block(64, 64, 1, 2), block(64, 64, 1, 4),
                                  block(64, 64, 1, 8), nn.Conv2d(64, 1, 1))

    def forward(self, x):
        return self.body(x)

    class Exported(nn.Module):
        def __init__(self, net):
            super().__init__()
            self.net = net

        def forward(self, x):
            return torch.sigmoid(self.net(x))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--recording", required=True, nargs="+",
                    help="simulator recordings (mapping kapture at their root), pooled")
    ap.add_argument("--out", required=True, help="output folder")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=128)
    ap.add_argument("--iterations", type=int, default=2000)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    if a.width % STRIDE or a.height % STRIDE:
        sys.exit(f"--width and --height must be multiples of {STRIDE}")
    torch.manual_seed(a.seed)
    torch.set_num_threads(a.threads)
    start = time.time()
    X, Y = [], []
    for recording in a.recording:
        k = kapture_io.Kapture(recording)
        before = len(X)
        for _, _, path in k.records:
            mask_file = os.path.join(recording, "truth", "masks", "mapping", os.path.splitext(path)[0] + ".png")
            if not os.path.exists(mask_file):
                continue
            X.append(kapture_io.normalise(kapture_io.load_image(k.image_file(path), a.width, a.height)))
            with Image.open(mask_file) as m:
                cells = m.convert("L").resize((a.width // STRIDE, a.height // STRIDE), Image.BOX)
            Y.append(np.asarray(cells, np.float32)[None] / 255.0)
        if len(X) == before:
            sys.exit(f"{recording}: no image with a mask under truth/masks/mapping")
    X, Y = torch.from_numpy(np.stack(X)), torch.from_numpy(np.stack(Y))
    person_share = float(Y.mean())
    print(f"{len(X)} images with masks, {person_share:.1%} of the cells on people", flush=True)
    net = PersonSegmentation()
    opt = torch.optim.Adam(net.parameters(), lr=a.lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, a.iterations)
    loss_value = float("nan")
    for it in range(a.iterations):
        net.train()
        idx = torch.randint(len(X), (a.batch,))
        loss = nn.functional.binary_cross_entropy_with_logits(net(augment(X[idx])), Y[idx])
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        loss_value = float(loss)
        if (it + 1) % max(1, a.iterations // 10) == 0:
            print(f"iteration {it + 1}/{a.iterations}: loss {loss_value:.4f}", flush=True)
    net.eval()
    with torch.no_grad():
        p = torch.sigmoid(net(X)) >= 0.5
        t = Y >= 0.5
        iou = float((p & t).sum()) / max(1.0, float((p | t).sum()))
    os.makedirs(a.out, exist_ok=True)
    onnx_file = os.path.join(a.out, "person_segmentation.onnx")
    atomic_export(PersonSegmentation.Exported(net), torch.zeros(1, 3, a.height, a.width), onnx_file, ["person"])
    total = time.time() - start
    atomic_json(os.path.join(a.out, "training.json"), {
        "recipe": "plugins/localizer/scene_regression/train/train_person_segmentation.py", "argv": sys.argv[1:],
        "recordings": [os.path.abspath(r) for r in a.recording], "images": len(X), "person_cell_share": person_share,
        "width": a.width, "height": a.height, "iterations": a.iterations, "batch": a.batch, "lr": a.lr,
        "threads": a.threads, "seed": a.seed, "final_loss": loss_value, "train_cell_iou": iou,
        "train_seconds": round(total, 1), "model_bytes": os.path.getsize(onnx_file),
        "torch": torch.__version__, "machine": platform.machine(), "cpus": os.cpu_count()})
    print(f"wrote {onnx_file}: train cell IoU {iou:.2f}, {total:.0f} s")


if __name__ == "__main__":
    main()

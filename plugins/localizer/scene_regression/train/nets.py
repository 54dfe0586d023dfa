"""The small CPU networks of the training recipes and their ONNX export.
Inputs: 1x3xHxW as localizer/posenet|esac prepare them (RGB, ImageNet mean/std)."""
import json
import os

import torch
import torch.nn as nn


def block(i, o, stride=1, dilation=1):
    return nn.Sequential(nn.Conv2d(i, o, 3, stride, dilation, dilation=dilation, bias=False),
                         nn.BatchNorm2d(o), nn.ReLU(inplace=True))


def encoder():
    """Five stride-2 blocks: 160x128 -> 5x4 x 256."""
    return nn.Sequential(block(3, 32, 2), block(32, 64, 2), block(64, 128, 2), block(128, 128, 2),
                         block(128, 256, 2))


class PoseNet(nn.Module):
    """Encoder, global average pooling, dropout, linear heads (centre, quaternion)."""

    def __init__(self):
        super().__init__()
        self.encoder = encoder()
        self.drop = nn.Dropout(0.3)
        self.position = nn.Linear(256, 3)
        self.orientation = nn.Linear(256, 4)
        with torch.no_grad():
            self.orientation.bias.copy_(torch.tensor([1.0, 0, 0, 0]))

    def forward(self, x):
        f = self.drop(torch.flatten(nn.functional.adaptive_avg_pool2d(self.encoder(x), 1), 1))
        return self.position(f), self.orientation(f)

    class Exported(nn.Module):
        """Positions back in the map's frame and metres."""

        def __init__(self, net, mean, scale):
            super().__init__()
            self.net = net
            self.register_buffer("mean", torch.tensor(mean, dtype=torch.float32).view(1, 3))
            self.scale = float(scale)

        def forward(self, x):
            c, q = self.net(x)
            return c * self.scale + self.mean, q


class Gating(nn.Module):
    """Encoder, pooling, linear: one logit per expert."""

    def __init__(self, experts):
        super().__init__()
        self.encoder = encoder()
        self.drop = nn.Dropout(0.3)
        self.head = nn.Linear(256, experts)

    def forward(self, x):
        return self.head(self.drop(torch.flatten(nn.functional.adaptive_avg_pool2d(self.encoder(x), 1), 1)))


class SceneCoordinates(nn.Module):
    """Fully convolutional, stride 8 (one scene coordinate per 8x8 input cell),
    dilated blocks for a receptive field of ~100 input pixels."""

    STRIDE = 8

    def __init__(self):
        super().__init__()
        self.body = nn.Sequential(block(3, 32, 2), block(32, 64, 2), block(64, 128, 2), block(128, 128, 1, 2),
                                  block(128, 128, 1, 4), block(128, 128, 1, 8),
                                  nn.Conv2d(128, 128, 1), nn.ReLU(inplace=True), nn.Conv2d(128, 3, 1))

    def forward(self, x):
        return self.body(x)

    class Exported(nn.Module):
        """Coordinates back in the map's frame and metres."""

        def __init__(self, net, centre, scale):
            super().__init__()
            self.net = net
            self.register_buffer("centre", torch.tensor(centre, dtype=torch.float32).view(1, 3, 1, 1))
            self.scale = float(scale)

        def forward(self, x):
            return self.net(x) * self.scale + self.centre


def augment(x):
    """Brightness and contrast jitter (in normalised units): poses unchanged."""
    n = x.shape[0]
    gain = 1 + (torch.rand(n, 1, 1, 1) - 0.5) * 0.4
    shift = (torch.rand(n, 1, 1, 1) - 0.5) * 0.4
    return x * gain + shift


def atomic_export(module, example, path, output_names):
    """torch.onnx.export to a temp file, then rename (an interrupted export leaves no model)."""
    module.eval()
    tmp = path + ".tmp"
    torch.onnx.export(module, example, tmp, input_names=["image"], output_names=output_names, opset_version=11,
                      do_constant_folding=True)
    os.replace(tmp, path)


def atomic_json(path, record):
    """The training record, written to a temp file then renamed."""
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(record, f, indent=1)
    os.replace(tmp, path)

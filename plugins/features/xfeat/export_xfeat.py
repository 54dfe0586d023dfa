#!/usr/bin/python3
"""XFeat (Potje et al., CVPR 2024) for features/xfeat: the network in PyTorch with
the authors' weights taken from their fixed-size ONNX export, exported again
with a free input size; and the authors' sparse extraction (detectAndCompute)
in PyTorch, as the reference the C++ stage is tested against.

Uses Debian's python3-torch (1.13) and python3-onnx, nothing else.

  export_xfeat.py export    [--weights X] --out xfeat.onnx
  export_xfeat.py reference [--weights X] --image IMG [--crop x,y,w,h] --out DIR [--keep N]

Weights: ../shared/models/xfeat/xfeat.onnx (Apache-2.0, the authors' own
export, 1x3x640x640). Its 27 convolutions are the network's convolutions with
the (affine-free) batch normalisations folded in, in the order of the modules
below; the instance normalisation has scale 1 and bias 0.

Exported model (opset 11), contract of features/xfeat:
  input  `image`       float32 1x1xHxW, H and W multiples of 32 (free):
                       the grey image = mean of R, G, B in [0, 1];
  output `descriptors` 1x64xH/8xW/8 dense descriptors (not normalised);
         `keypoints`   1x65xH/8xW/8 keypoint logits (64 positions of the 8x8
                       cell, row-major, + a "no keypoint" bin);
         `reliability` 1x1xH/8xW/8 in [0, 1].
The grey conversion (the authors' x.mean(dim=1)) is left to the caller: it is
linear, so it commutes with the authors' resize to multiples of 32, and the
graph stays free of reductions OpenCV 4.6 cannot size at run time.
"""
import argparse
import os
import struct
import sys

import numpy as np
import onnx
from onnx import numpy_helper
import torch
import torch.nn as nn
import torch.nn.functional as F

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_WEIGHTS = os.path.normpath(os.path.join(HERE, '../../../../shared/models/xfeat/xfeat.onnx'))


def conv_relu(cin, cout, k=3, stride=1):
    """The authors' BasicLayer (conv, BatchNorm without affine, ReLU) with the
    normalisation folded into the convolution's bias, as in their ONNX."""
    return nn.Sequential(nn.Conv2d(cin, cout, k, stride=stride, padding=k // 2), nn.ReLU())


class XFeatNet(nn.Module):
    """XFeat's backbone and heads (modules/model.py of verlab/accelerated_features),
    written for a free input size: the 8x8 space-to-depth of the keypoint head is a
    fixed one-hot convolution of stride 8 (exactly the authors' unfold), the
    pyramid fusion upsamples by the factors 2 and 4 (sizes are multiples of 32)."""

    def __init__(self):
        super().__init__()
        self.norm = nn.InstanceNorm2d(1)
        self.block1 = nn.Sequential(conv_relu(1, 4), conv_relu(4, 8, stride=2), conv_relu(8, 8),
                                    conv_relu(8, 24, stride=2))
        self.skip1 = nn.Sequential(nn.AvgPool2d(4, stride=4), nn.Conv2d(1, 24, 1))
        self.block2 = nn.Sequential(conv_relu(24, 24), conv_relu(24, 24))
        self.block3 = nn.Sequential(conv_relu(24, 64, stride=2), conv_relu(64, 64), conv_relu(64, 64, k=1))
        self.block4 = nn.Sequential(conv_relu(64, 64, stride=2), conv_relu(64, 64), conv_relu(64, 64))
        self.block5 = nn.Sequential(conv_relu(64, 128, stride=2), conv_relu(128, 128),
                                    conv_relu(128, 128), conv_relu(128, 64, k=1))
        self.block_fusion = nn.Sequential(conv_relu(64, 64), conv_relu(64, 64), nn.Conv2d(64, 64, 1))
        self.heatmap_head = nn.Sequential(conv_relu(64, 64, k=1), conv_relu(64, 64, k=1),
                                          nn.Conv2d(64, 1, 1), nn.Sigmoid())
        self.keypoint_head = nn.Sequential(conv_relu(64, 64, k=1), conv_relu(64, 64, k=1),
                                           conv_relu(64, 64, k=1), nn.Conv2d(64, 65, 1))
        # Space-to-depth 8x8: output channel i*8+j = input pixel (8y+i, 8x+j).
        s2d = torch.zeros(64, 1, 8, 8)
        for i in range(8):
            for j in range(8):
                s2d[i * 8 + j, 0, i, j] = 1.0
        self.register_buffer('space_to_depth', s2d)

    def convolutions(self):
        """The convolutions in the order of the authors' ONNX graph."""
        blocks = [self.block1, self.skip1, self.block2, self.block3, self.block4, self.block5,
                  self.block_fusion, self.heatmap_head, self.keypoint_head]
        return [m for b in blocks for m in b.modules() if isinstance(m, nn.Conv2d)]

    def forward(self, grey):
        x = self.norm(grey)
        x1 = self.block1(x)
        x2 = self.block2(x1 + self.skip1(x))
        x3 = self.block3(x2)
        x4 = self.block4(x3)
        x5 = self.block5(x4)
        x4 = F.interpolate(x4, scale_factor=2.0, mode='bilinear', align_corners=False)
        x5 = F.interpolate(x5, scale_factor=4.0, mode='bilinear', align_corners=False)
        feats = self.block_fusion(x3 + x4 + x5)
        heatmap = self.heatmap_head(feats)
        keypoints = self.keypoint_head(F.conv2d(x, self.space_to_depth, stride=8))
        return feats, keypoints, heatmap


def load_net(weights):
    """XFeatNet with the weights of the authors' ONNX export."""
    model = onnx.load(weights)
    init = {t.name: numpy_helper.to_array(t) for t in model.graph.initializer}
    convs = [n for n in model.graph.node if n.op_type == 'Conv']
    net = XFeatNet().eval()
    mine = net.convolutions()
    if len(convs) != len(mine):
        sys.exit(f'{weights}: {len(convs)} convolutions, XFeat has {len(mine)}')
    for node, conv in zip(convs, mine):
        w, b = init[node.input[1]], init[node.input[2]]
        if tuple(w.shape) != tuple(conv.weight.shape):
            sys.exit(f'{weights}: convolution {node.name} has weights {w.shape}, '
                     f'expected {tuple(conv.weight.shape)}')
        stride = [a.ints for a in node.attribute if a.name == 'strides'][0]
        if tuple(stride) != conv.stride:
            sys.exit(f'{weights}: convolution {node.name} has stride {stride}, expected {conv.stride}')
        conv.weight.data = torch.from_numpy(w.copy())
        conv.bias.data = torch.from_numpy(b.copy())
    for node in model.graph.node:
        if node.op_type == 'InstanceNormalization':
            eps = [a.f for a in node.attribute if a.name == 'epsilon'][0]
            if abs(eps - net.norm.eps) > 1e-9:
                sys.exit(f'{weights}: instance normalisation epsilon {eps}, expected {net.norm.eps}')
    return net, model


def export(args):
    net, _ = load_net(args.weights)
    grey = torch.rand(1, 1, 480, 640)
    torch.onnx.export(net, grey, args.out, opset_version=11, input_names=['image'],
                      output_names=['descriptors', 'keypoints', 'reliability'],
                      dynamic_axes={'image': {2: 'H', 3: 'W'}, 'descriptors': {2: 'h', 3: 'w'},
                                    'keypoints': {2: 'h', 3: 'w'}, 'reliability': {2: 'h', 3: 'w'}})
    onnx.checker.check_model(onnx.load(args.out))
    print(f'wrote {args.out}')


# --------------------------------------------------------------------------
# The authors' sparse extraction (modules/xfeat.py, XFeat.detectAndCompute),
# written out with torch ops: the reference of the C++ stage.

def grid(pos, H, W):
    """The authors' InterpolateSparse2d normalisation: x / (W - 1) * 2 - 1."""
    return 2.0 * (pos / torch.tensor([W - 1, H - 1], dtype=pos.dtype)) - 1.0


def sample(x, pos, H, W, mode):
    g = grid(pos, H, W).view(1, -1, 1, 2).to(x.dtype)
    return F.grid_sample(x, g, mode=mode, align_corners=False)[0, :, :, 0].t()  # N x C


def detect_and_compute(net, rgb, top_k=4096, threshold=0.05):
    """rgb: HxWx3 uint8. Returns keypoints (N x 2, the authors' coordinates:
    pixel index in the resized image times W / W32), scores, descriptors."""
    x = torch.from_numpy(rgb).permute(2, 0, 1)[None].float() / 255.0
    H, W = x.shape[-2:]
    H32, W32 = (H // 32) * 32, (W // 32) * 32
    rh, rw = H / H32, W / W32
    x = F.interpolate(x, (H32, W32), mode='bilinear', align_corners=False)
    with torch.no_grad():
        M, K, R = net(x.mean(dim=1, keepdim=True))
    M = F.normalize(M, dim=1)
    # 65 logits -> softmax -> drop the dustbin -> full-resolution heatmap.
    p = F.softmax(K, 1)[:, :64]
    _, _, h, w = p.shape
    heat = p.permute(0, 2, 3, 1).reshape(1, h, w, 8, 8).permute(0, 1, 3, 2, 4).reshape(1, 1, h * 8, w * 8)
    # 5x5 non-maximum suppression, threshold.
    local_max = F.max_pool2d(heat, 5, stride=1, padding=2)
    pos = ((heat == local_max) & (heat > threshold))[0, 0].nonzero().flip(-1).float()  # (x, y)
    scores = (sample(heat, pos, H32, W32, 'nearest') * sample(R, pos, H32, W32, 'bilinear'))[:, 0]
    scores[(pos == 0).all(dim=1)] = -1
    order = torch.argsort(-scores, stable=True)[:top_k]
    pos, scores = pos[order], scores[order]
    desc = F.normalize(sample(M, pos, H32, W32, 'bicubic'), dim=-1)
    valid = scores > 0
    kpts = pos * torch.tensor([rw, rh])
    return kpts[valid].numpy(), scores[valid].numpy(), desc[valid].numpy(), pos[valid].numpy()


def read_rgb(path, crop):
    from PIL import Image
    rgb = np.asarray(Image.open(path).convert('RGB'))
    if crop:
        x, y, w, h = crop
        rgb = rgb[y:y + h, x:x + w]
    return np.ascontiguousarray(rgb)


def reference(args):
    net, _ = load_net(args.weights)
    crop = [int(v) for v in args.crop.split(',')] if args.crop else None
    rgb = read_rgb(args.image, crop)
    kpts, scores, desc, _ = detect_and_compute(net, rgb, top_k=args.top_k)
    n = min(args.keep, len(scores))
    os.makedirs(args.out, exist_ok=True)
    kpts[:n].astype('<f4').tofile(os.path.join(args.out, 'xfeat.kpt.f32'))
    scores[:n].astype('<f4').tofile(os.path.join(args.out, 'xfeat.scores.f32'))
    desc[:n].astype('<f2').tofile(os.path.join(args.out, 'xfeat.desc.f16'))
    with open(os.path.join(args.out, 'xfeat.txt'), 'w') as f:
        f.write(f'image {os.path.basename(args.image)}\ncrop {args.crop or ""}\n'
                f'size {rgb.shape[1]} {rgb.shape[0]}\npixel_sum {int(rgb.astype(np.int64).sum())}\n'
                f'top_k {args.top_k}\nkeypoints {len(scores)}\nstored {n}\n')
    print(f'{len(scores)} keypoints, stored the best {n} in {args.out}')


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest='command', required=True)
    e = sub.add_parser('export', help='export the free-size ONNX model')
    e.add_argument('--weights', default=DEFAULT_WEIGHTS, help='the authors\' xfeat.onnx')
    e.add_argument('--out', required=True)
    r = sub.add_parser('reference', help='the authors\' extraction in PyTorch on one image')
    r.add_argument('--weights', default=DEFAULT_WEIGHTS)
    r.add_argument('--image', required=True)
    r.add_argument('--crop', default='', help='x,y,w,h of the image to use')
    r.add_argument('--top_k', type=int, default=4096)
    r.add_argument('--keep', type=int, default=1000, help='keypoints stored (best first)')
    r.add_argument('--out', required=True)
    args = ap.parse_args()
    if not os.path.exists(args.weights):
        sys.exit(f'{args.weights}: not found (the authors\' XFeat ONNX, ../shared/models/xfeat)')
    torch.set_grad_enabled(False)
    {'export': export, 'reference': reference}[args.command](args)


if __name__ == '__main__':
    main()

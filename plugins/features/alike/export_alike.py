#!/usr/bin/python3
"""ALIKE (Zhao et al., IEEE TMM 2022) for features/alike: the network in
PyTorch with the authors' state dicts, exported to ONNX with a free input size;
and the authors' extraction (ALike.forward with sub-pixel DKD) in PyTorch, as
the reference the C++ stage is tested against.

Uses Debian's python3-torch (1.13) and python3-onnx, nothing else.

  export_alike.py export    --size n [--weights X] --out alike-n.onnx
  export_alike.py reference --size n [--weights X] --image IMG [--crop x,y,w,h] --out DIR [--keep N]

Weights: ../shared/models/alike/alike-{t,s,n,l}.pth (BSD-3-Clause).

Exported model (opset 11), contract of features/alike:
  input  `image`       float32 1x3xHxW, RGB in [0, 1], H and W multiples of 32
                       (free; the authors pad with zeros to get there);
  output `scores`      1x1xHxW score map in [0, 1];
         `descriptors` 1xDxHxW dense descriptors, not normalised (D = 64, 96,
                       128, 128 for t, s, n, l).
"""
import argparse
import os
import sys

import numpy as np
import onnx
import torch
import torch.nn as nn
import torch.nn.functional as F

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.path.normpath(os.path.join(HERE, '../../../../shared/models/alike'))

# The authors' configurations (alike.py `configs`): c1..c4, dim, single head.
CONFIGS = {
    't': (8, 16, 32, 64, 64, True),
    's': (8, 16, 48, 96, 96, True),
    'n': (16, 32, 64, 128, 128, True),
    'l': (32, 64, 128, 128, 128, False),
}


def conv3x3(cin, cout):
    return nn.Conv2d(cin, cout, 3, padding=1, bias=False)


def conv1x1(cin, cout):
    return nn.Conv2d(cin, cout, 1, bias=False)


class ConvBlock(nn.Module):
    """Two 3x3 conv + BN + ReLU (alnet.py ConvBlock)."""

    def __init__(self, cin, cout):
        super().__init__()
        self.conv1, self.bn1 = conv3x3(cin, cout), nn.BatchNorm2d(cout)
        self.conv2, self.bn2 = conv3x3(cout, cout), nn.BatchNorm2d(cout)

    def forward(self, x):
        return F.relu(self.bn2(self.conv2(F.relu(self.bn1(self.conv1(x))))))


class ResBlock(nn.Module):
    """torchvision's BasicBlock, stride 1, with a 1x1 conv (with bias) shortcut."""

    def __init__(self, cin, cout):
        super().__init__()
        self.conv1, self.bn1 = conv3x3(cin, cout), nn.BatchNorm2d(cout)
        self.conv2, self.bn2 = conv3x3(cout, cout), nn.BatchNorm2d(cout)
        self.downsample = nn.Conv2d(cin, cout, 1)

    def forward(self, x):
        out = self.bn2(self.conv2(F.relu(self.bn1(self.conv1(x)))))
        return F.relu(out + self.downsample(x))


class ALNet(nn.Module):
    """The encoder (1, 1/2, 1/8, 1/32), the aggregation of the four scales
    (1x1 conv + ReLU each, bilinear upsampling with align_corners, concat) and
    the head (dim descriptor channels + one score channel)."""

    def __init__(self, c1, c2, c3, c4, dim, single_head):
        super().__init__()
        self.dim = dim
        self.single_head = single_head
        self.block1 = ConvBlock(3, c1)
        self.block2 = ResBlock(c1, c2)
        self.block3 = ResBlock(c2, c3)
        self.block4 = ResBlock(c3, c4)
        self.conv1 = conv1x1(c1, dim // 4)
        self.conv2 = conv1x1(c2, dim // 4)
        self.conv3 = conv1x1(c3, dim // 4)
        self.conv4 = conv1x1(dim, dim // 4)
        if not single_head:
            self.convhead1 = conv1x1(dim, dim)
        self.convhead2 = conv1x1(dim, dim + 1)

    def forward(self, image):
        x1 = self.block1(image)
        x2 = self.block2(F.max_pool2d(x1, 2, 2))
        x3 = self.block3(F.max_pool2d(x2, 4, 4))
        x4 = self.block4(F.max_pool2d(x3, 4, 4))
        up = lambda x, s: F.interpolate(x, scale_factor=float(s), mode='bilinear', align_corners=True)
        x = torch.cat([F.relu(self.conv1(x1)), up(F.relu(self.conv2(x2)), 2),
                       up(F.relu(self.conv3(x3)), 8), up(F.relu(self.conv4(x4)), 32)], dim=1)
        if not self.single_head:
            x = F.relu(self.convhead1(x))
        x = self.convhead2(x)
        # Slices, not x[:, -1] + unsqueeze: OpenCV 4.6 refuses the Unsqueeze.
        return torch.sigmoid(x[:, self.dim:self.dim + 1]), x[:, :self.dim]


def load_net(size, weights):
    net = ALNet(*CONFIGS[size]).eval()
    state = torch.load(weights, map_location='cpu')
    net.load_state_dict(state, strict=True)
    return net


def export(args):
    net = load_net(args.size, args.weights)
    torch.onnx.export(net, torch.rand(1, 3, 480, 640), args.out, opset_version=11,
                      input_names=['image'], output_names=['scores', 'descriptors'],
                      dynamic_axes={'image': {2: 'H', 3: 'W'}, 'scores': {2: 'H', 3: 'W'},
                                    'descriptors': {2: 'H', 3: 'W'}})
    onnx.checker.check_model(onnx.load(args.out))
    print(f'wrote {args.out}')


# --------------------------------------------------------------------------
# The authors' extraction (alike.py ALike.forward, soft_detect.py DKD with
# sub_pixel=True; demo defaults top_k -1, scores_th 0.2, n_limit 5000, radius 2)
# written out with torch ops: the reference of the C++ stage.

def simple_nms(scores, radius):
    pool = lambda x: F.max_pool2d(x, 2 * radius + 1, stride=1, padding=radius)
    zeros = torch.zeros_like(scores)
    max_mask = scores == pool(scores)
    for _ in range(2):
        supp_mask = pool(max_mask.float()) > 0
        supp_scores = torch.where(supp_mask, zeros, scores)
        new_max_mask = supp_scores == pool(supp_scores)
        max_mask = max_mask | (new_max_mask & (~supp_mask))
    return torch.where(max_mask, scores, zeros)


def extract(net, rgb, radius=2, top_k=-1, scores_th=0.2, n_limit=5000):
    """rgb: HxWx3 uint8. Returns keypoints (N x 2, pixels, first centre at 0),
    scores, descriptors (N x D), sorted by decreasing score."""
    image = torch.from_numpy(rgb).float().permute(2, 0, 1)[None] / 255.0
    _, _, h, w = image.shape
    h32, w32 = -(-h // 32) * 32, -(-w // 32) * 32
    padded = F.pad(image, (0, w32 - w, 0, h32 - h))
    scores_map, desc_map = net(padded)
    scores_map, desc_map = scores_map[:, :, :h, :w].contiguous(), desc_map[:, :, :h, :w].contiguous()
    desc_map = F.normalize(desc_map, p=2, dim=1)

    nms = simple_nms(scores_map, 2)
    nms[:, :, :radius + 1, :] = 0
    nms[:, :, :, :radius + 1] = 0
    nms[:, :, h - radius:, :] = 0
    nms[:, :, :, w - radius:] = 0
    flat_nms, flat = nms.view(-1), scores_map.view(-1)
    if top_k > 0:
        indices = torch.topk(flat_nms, top_k).indices
    else:
        mask = flat_nms > scores_th
        if mask.sum() == 0:
            mask = flat_nms > flat.mean()
        indices = mask.nonzero()[:, 0]
        if len(indices) > n_limit:
            indices = indices[flat[indices].sort(descending=True)[1][:n_limit]]

    k = 2 * radius + 1
    patches = F.unfold(scores_map, kernel_size=k, padding=radius)[0].t()[indices]  # M x k*k
    lin = torch.linspace(-radius, radius, k)
    gy, gx = torch.meshgrid(lin, lin, indexing='ij')
    hw_grid = torch.stack([gx.reshape(-1), gy.reshape(-1)], dim=1)  # (x, y) offsets
    e = ((patches - patches.max(dim=1).values[:, None]) / 0.1).exp()
    residual = e @ hw_grid / e.sum(dim=1)[:, None]
    xy = torch.stack([indices % w, indices // w], dim=1).float() + residual
    norm = xy / torch.tensor([w - 1, h - 1], dtype=xy.dtype) * 2 - 1
    g = norm.view(1, 1, -1, 2)
    kscores = F.grid_sample(scores_map, g, mode='bilinear', align_corners=True)[0, 0, 0]
    desc = F.grid_sample(desc_map, g, mode='bilinear', align_corners=True)[0, :, 0].t()
    desc = F.normalize(desc, p=2, dim=1)
    kpts = (norm + 1) / 2 * torch.tensor([w - 1, h - 1], dtype=norm.dtype)
    order = torch.argsort(-kscores, stable=True)
    return kpts[order].numpy(), kscores[order].numpy(), desc[order].numpy()


def read_rgb(path, crop):
    from PIL import Image
    rgb = np.asarray(Image.open(path).convert('RGB'))
    if crop:
        x, y, w, h = crop
        rgb = rgb[y:y + h, x:x + w]
    return np.ascontiguousarray(rgb)


def reference(args):
    net = load_net(args.size, args.weights)
    crop = [int(v) for v in args.crop.split(',')] if args.crop else None
    rgb = read_rgb(args.image, crop)
    kpts, scores, desc = extract(net, rgb)
    n = min(args.keep, len(scores))
    os.makedirs(args.out, exist_ok=True)
    stem = os.path.join(args.out, f'alike-{args.size}')
    kpts[:n].astype('<f4').tofile(stem + '.kpt.f32')
    scores[:n].astype('<f4').tofile(stem + '.scores.f32')
    desc[:n].astype('<f2').tofile(stem + '.desc.f16')
    with open(stem + '.txt', 'w') as f:
        f.write(f'image {os.path.basename(args.image)}\ncrop {args.crop or ""}\n'
                f'size {rgb.shape[1]} {rgb.shape[0]}\npixel_sum {int(rgb.astype(np.int64).sum())}\n'
                f'dim {desc.shape[1]}\nkeypoints {len(scores)}\nstored {n}\n')
    print(f'alike-{args.size}: {len(scores)} keypoints, stored the best {n} in {args.out}')


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest='command', required=True)
    for name in ('export', 'reference'):
        p = sub.add_parser(name)
        p.add_argument('--size', choices=sorted(CONFIGS), required=True)
        p.add_argument('--weights', default='', help='state dict (default: ../shared/models/alike/alike-SIZE.pth)')
        p.add_argument('--out', required=True)
        if name == 'reference':
            p.add_argument('--image', required=True)
            p.add_argument('--crop', default='', help='x,y,w,h of the image to use')
            p.add_argument('--keep', type=int, default=400, help='keypoints stored (best first)')
    args = ap.parse_args()
    args.weights = args.weights or os.path.join(SHARED, f'alike-{args.size}.pth')
    if not os.path.exists(args.weights):
        sys.exit(f'{args.weights}: not found (the authors\' ALIKE weights, ../shared/models/alike)')
    torch.set_grad_enabled(False)
    {'export': export, 'reference': reference}[args.command](args)


if __name__ == '__main__':
    main()

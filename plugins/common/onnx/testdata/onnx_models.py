#!/usr/bin/env python3
"""Small architecture-faithful ONNX models for the learned plugin's tests, and
their numpy forward passes (the expected outputs the C++ plugin must match).

  onnx_models.py make DIR [NETVLAD_H NETVLAD_W]
      writes DIR/{netvlad,gem,d2net}.onnx and DIR/<model>.npz (their weights),
      deterministic (seeded); the NetVLAD model's fixed input size is 48 x 64
      unless given.
  onnx_models.py forward MODEL DIR INPUT.f32 C H W OUTPUT.f32
      numpy forward pass of DIR/MODEL.npz on a float32 1 x C x H x W input
      (raw little-endian); writes the output raw float32 and prints its shape.
  onnx_models.py d2net DIR IMAGE.u8 H W SCALES authors|soft PREFIX
      D2-Net extraction (numpy port of the authors' process_multiscale) of an
      H x W x 3 RGB uint8 image with the d2net test model at SCALES ("0.5,1,2");
      writes PREFIX.kpt (N x 3 float32: x, y, 1/scale, the authors' pixel-index
      coordinates), PREFIX.scores (N) and PREFIX.desc (N x C); prints N.

Needs python3-onnx (Debian) and python3-numpy. The models follow the
contracts of plugins/common/onnx/README.md:
  netvlad: conv trunk -> descriptors L2-normalised over channels -> NetVLAD
           layer (1x1 conv soft-assignment + softmax over clusters, residual
           aggregation sum_n a_kn (x_n - c_k) as a MatMul, intra-normalisation,
           flatten); input "image" 1x3xHxW, output "descriptor" 1 x K*C.
  gem:     conv trunk -> ReLU -> GeM pooling ((mean x^p)^(1/p) of x clamped at
           1e-6, p learnt) -> FC whitening (with bias); output
           "descriptor" 1 x D (AP-GeM's head).
  The final L2 normalisation of the descriptor is left to the plugin: OpenCV
  4.6's importer refuses the broadcast division of a 1 x D tensor by its norm
  (findBroadAxis assertion), so exports stop before it. The numpy forwards
  below include it (they give what the plugin must output).
  d2net:   VGG16-like trunk with D2-Net's modifications: two 2x2/2 max pools
           (output stride 4), the third pool a 2x2 average pool of stride 1,
           the last block dilated (dilation 2, padding 2), final ReLU; output
           "features" 1 x C x (H/4 - 1) x (W/4 - 1).
"""
import sys

import numpy as np

OPSET = 11
K_CLUSTERS = 4
NETVLAD_H, NETVLAD_W = 48, 64  # input size of the NetVLAD test model (resize: fixed)


def conv_w(rng, cout, cin, k):
    return (rng.standard_normal((cout, cin, k, k)) * np.sqrt(2.0 / (cin * k * k))).astype(np.float32)


def specs():
    rng = np.random.default_rng(7)
    s = {}
    # NetVLAD: conv(3->8) relu maxpool conv(8->16) [no ReLU, like conv5_3 in
    # the Pitts30k models], netvlad K=4 clusters over C=16.
    s["netvlad"] = {
        "w1": conv_w(rng, 8, 3, 3), "b1": (0.1 * rng.standard_normal(8)).astype(np.float32),
        "w2": conv_w(rng, 16, 8, 3), "b2": (0.1 * rng.standard_normal(16)).astype(np.float32),
        "wa": (3 * rng.standard_normal((K_CLUSTERS, 16, 1, 1))).astype(np.float32),
        "ba": (0.1 * rng.standard_normal(K_CLUSTERS)).astype(np.float32),
        "centroids": (0.3 * rng.standard_normal((K_CLUSTERS, 16))).astype(np.float32),
    }
    # GeM + whitening: conv(3->8) relu maxpool conv(8->12) relu, GeM p=3,
    # FC 12 -> 6 with bias.
    s["gem"] = {
        "w1": conv_w(rng, 8, 3, 3), "b1": (0.1 * rng.standard_normal(8)).astype(np.float32),
        "w2": conv_w(rng, 12, 8, 3), "b2": (0.1 * rng.standard_normal(12)).astype(np.float32),
        "p": np.array([3.0], np.float32),
        "wf": (rng.standard_normal((6, 12)) / np.sqrt(12)).astype(np.float32),
        "bf": (0.1 * rng.standard_normal(6)).astype(np.float32),
    }
    # D2-Net: conv conv pool conv pool conv avgpool(2, stride 1) dconv dconv relu
    # (VGG16 conv1_1..conv4_3 with fewer layers and channels).
    s["d2net"] = {
        "w1": conv_w(rng, 6, 3, 3), "b1": (0.1 * rng.standard_normal(6)).astype(np.float32),
        "w2": conv_w(rng, 6, 6, 3), "b2": (0.1 * rng.standard_normal(6)).astype(np.float32),
        "w3": conv_w(rng, 8, 6, 3), "b3": (0.1 * rng.standard_normal(8)).astype(np.float32),
        "w4": conv_w(rng, 8, 8, 3), "b4": (0.1 * rng.standard_normal(8)).astype(np.float32),
        "w5": conv_w(rng, 16, 8, 3), "b5": (0.1 * rng.standard_normal(16)).astype(np.float32),
        "w6": conv_w(rng, 16, 16, 3), "b6": (0.1 * rng.standard_normal(16)).astype(np.float32),
    }
    return s


# ----------------------------------------------------------------- ONNX graphs

def build_onnx(name, p):
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    nodes, inits = [], []

    def const(n, arr):
        inits.append(numpy_helper.from_array(np.asarray(arr), n))
        return n

    def node(op, ins, outs, **attrs):
        nodes.append(helper.make_node(op, ins, outs, **attrs))
        return outs[0]

    def clamp_min(x, eps, out):
        # max(x, eps) = relu(x - eps) + eps: OpenCV 4.6 reads Clip only in its
        # opset-6 form (min as an attribute), and torch writes Clip(x, min) for
        # clamp_min at opset >= 11.
        e = const(out + "_eps", np.array(eps, np.float32))
        t = node("Sub", [x, e], [out + "_s"])
        t = node("Relu", [t], [out + "_r"])
        return node("Add", [t, e], [out])

    def l2_normalise(x, axis, out):
        # F.normalize(x, dim=axis): x / max(||x||, 1e-12) (LpNormalization is
        # not in OpenCV 4.6).
        n = node("ReduceL2", [x], [out + "_norm"], axes=[axis], keepdims=1)
        n = clamp_min(n, 1e-12, out + "_clamped")
        return node("Div", [x, n], [out])

    def conv(x, w, b, out, pad=1, dil=1):
        k = p[w].shape[2]
        return node("Conv", [x, const(w, p[w]), const(b, p[b])], [out], kernel_shape=[k, k],
                    pads=[pad] * 4, dilations=[dil, dil], strides=[1, 1])

    x = "image"
    if name == "netvlad":
        t = node("Relu", [conv(x, "w1", "b1", "c1")], ["r1"])
        t = node("MaxPool", [t], ["p1"], kernel_shape=[2, 2], strides=[2, 2])
        t = conv(t, "w2", "b2", "c2")
        t = l2_normalise(t, 1, "xn")       # descriptors
        a = node("Conv", ["xn", const("wa", p["wa"]), const("ba", p["ba"])], ["sa"],
                 kernel_shape=[1, 1])
        # Softmax over the clusters (axis 1): at opset 11 ONNX Softmax flattens
        # the axes after `axis`, so the clusters go last first.
        a = node("Reshape", [a, const("shape_a", np.array([1, K_CLUSTERS, -1], np.int64))], ["sa3"])
        a = node("Transpose", [a], ["sat"], perm=[0, 2, 1])
        a = node("Softmax", [a], ["at"], axis=2)                      # soft-assignment
        af = node("Transpose", [a], ["af"], perm=[0, 2, 1])
        c = p["centroids"].shape[1]
        xf = node("Reshape", ["xn", const("shape_x", np.array([1, c, -1], np.int64))], ["xf"])
        xt = node("Transpose", [xf], ["xt"], perm=[0, 2, 1])
        ax = node("MatMul", [af, xt], ["ax"])                         # sum_n a_kn x_n
        asum = node("ReduceSum", [af], ["asum"], axes=[2], keepdims=1)  # sum_n a_kn
        # sum_n a_kn c_k: the sums broadcast over C by a MatMul with ones (OpenCV
        # 4.6 cannot broadcast a 1xKx1 tensor against a 1xKxC constant in Mul).
        asum = node("MatMul", [asum, const("ones_c", np.ones((1, c), np.float32))], ["asum_c"])
        ac = node("Mul", [asum, const("centroids", p["centroids"][None])], ["ac"])
        v = node("Sub", [ax, ac], ["vlad"])
        v = l2_normalise(v, 2, "intra")      # intra-normalisation
        # The final L2 normalisation is the plugin's (see below).
        node("Reshape", [v, const("shape_v", np.array([1, -1], np.int64))], ["descriptor"])
        out_shape = [1, K_CLUSTERS * c]
        out = "descriptor"
    elif name == "gem":
        t = node("Relu", [conv(x, "w1", "b1", "c1")], ["r1"])
        t = node("MaxPool", [t], ["p1"], kernel_shape=[2, 2], strides=[2, 2])
        t = node("Relu", [conv(t, "w2", "b2", "c2")], ["r2"])
        t = clamp_min(t, 1e-6, "clamped")
        t = node("Pow", [t, const("p", p["p"])], ["powered"])
        t = node("GlobalAveragePool", [t], ["mean"])
        t = node("Pow", [t, const("inv_p", (1.0 / p["p"]).astype(np.float32))], ["gem"])
        t = node("Flatten", [t], ["gemf"], axis=1)
        node("Gemm", [t, const("wf", p["wf"]), const("bf", p["bf"])], ["descriptor"], transB=1)
        out_shape = [1, p["wf"].shape[0]]
        out = "descriptor"
    elif name == "d2net":
        t = node("Relu", [conv(x, "w1", "b1", "c1")], ["r1"])
        t = node("MaxPool", [t], ["p1"], kernel_shape=[2, 2], strides=[2, 2])
        t = node("Relu", [conv(t, "w2", "b2", "c2")], ["r2"])
        t = node("MaxPool", [t], ["p2"], kernel_shape=[2, 2], strides=[2, 2])
        t = node("Relu", [conv(t, "w3", "b3", "c3")], ["r3"])
        t = node("Relu", [conv(t, "w4", "b4", "c4")], ["r4"])
        t = node("AveragePool", [t], ["p3"], kernel_shape=[2, 2], strides=[1, 1])
        t = node("Relu", [conv(t, "w5", "b5", "c5", pad=2, dil=2)], ["r5"])
        t = conv(t, "w6", "b6", "c6", pad=2, dil=2)
        node("Relu", [t], ["features"])
        out_shape = [1, p["w6"].shape[0], "h", "w"]
        out = "features"
    else:
        raise SystemExit("unknown model " + name)

    # NetVLAD takes a fixed input size (the importer of OpenCV 4.6 cannot
    # reduce over channels with dynamic spatial dims); the others any size.
    in_shape = [1, 3, NETVLAD_H, NETVLAD_W] if name == "netvlad" else [1, 3, "H", "W"]
    graph = helper.make_graph(
        nodes, name,
        [helper.make_tensor_value_info("image", TensorProto.FLOAT, in_shape)],
        [helper.make_tensor_value_info(out, TensorProto.FLOAT, out_shape)], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)],
                              producer_name="locforge learned tests")
    model.ir_version = 7
    onnx.checker.check_model(model)
    return model


# ------------------------------------------------------------ numpy forwards

def np_conv(x, w, b, pad=1, dil=1):
    """x: C x H x W, w: O x C x k x k -> O x H' x W' (stride 1)."""
    c, h, wd = x.shape
    o, _, k, _ = w.shape
    xp = np.pad(x, ((0, 0), (pad, pad), (pad, pad))).astype(np.float64)
    ho = h + 2 * pad - dil * (k - 1)
    wo = wd + 2 * pad - dil * (k - 1)
    out = np.zeros((o, ho, wo))
    for i in range(k):
        for j in range(k):
            patch = xp[:, i * dil:i * dil + ho, j * dil:j * dil + wo]
            out += np.einsum("oc,chw->ohw", w[:, :, i, j].astype(np.float64), patch)
    return out + b[:, None, None]


def np_maxpool2(x):
    c, h, w = x.shape
    h2, w2 = h // 2, w // 2
    return x[:, :2 * h2, :2 * w2].reshape(c, h2, 2, w2, 2).max(axis=(2, 4))


def np_avgpool2_s1(x):
    return 0.25 * (x[:, :-1, :-1] + x[:, 1:, :-1] + x[:, :-1, 1:] + x[:, 1:, 1:])


def l2n(v, axis):
    return v / np.maximum(np.linalg.norm(v, axis=axis, keepdims=True), 1e-12)


def forward(name, p, x):
    """x: 3 x H x W float64 -> the model's output (without the batch axis)."""
    relu = lambda t: np.maximum(t, 0)
    if name == "netvlad":
        t = np_maxpool2(relu(np_conv(x, p["w1"], p["b1"])))
        t = np_conv(t, p["w2"], p["b2"])
        xn = l2n(t, 0)                                       # C x H x W
        logits = np_conv(xn, p["wa"], p["ba"], pad=0)        # K x H x W
        e = np.exp(logits - logits.max(axis=0, keepdims=True))
        a = (e / e.sum(axis=0, keepdims=True)).reshape(K_CLUSTERS, -1)
        xf = xn.reshape(xn.shape[0], -1)                     # C x N
        # V(k, c) = sum_n a_kn (x_cn - c_kc)   (NetVLAD, Arandjelovic et al. eq. 1/4)
        v = np.stack([(a[k][None, :] * (xf - p["centroids"][k][:, None])).sum(axis=1)
                      for k in range(K_CLUSTERS)])
        v = l2n(v, 1)                                        # intra-normalisation
        return l2n(v.reshape(-1), 0)
    if name == "gem":
        t = np_maxpool2(relu(np_conv(x, p["w1"], p["b1"])))
        t = relu(np_conv(t, p["w2"], p["b2"]))
        pp = float(p["p"][0])
        g = (np.maximum(t, 1e-6) ** pp).mean(axis=(1, 2)) ** (1.0 / pp)
        return l2n(p["wf"] @ g + p["bf"], 0)
    if name == "d2net":
        t = np_maxpool2(relu(np_conv(x, p["w1"], p["b1"])))
        t = np_maxpool2(relu(np_conv(t, p["w2"], p["b2"])))
        t = relu(np_conv(t, p["w3"], p["b3"]))
        t = np_avgpool2_s1(relu(np_conv(t, p["w4"], p["b4"])))
        t = relu(np_conv(t, p["w5"], p["b5"], pad=2, dil=2))
        return relu(np_conv(t, p["w6"], p["b6"], pad=2, dil=2))
    raise SystemExit("unknown model " + name)


# ------------------------------------------- D2-Net extraction (numpy port)
# A port of the authors' lib/pyramid.py process_multiscale with
# lib/model_test.py's HardDetectionModule, HandcraftedLocalizationModule and
# SoftDetectionModule and lib/utils.py's interpolate_dense_features /
# upscale_positions (https://github.com/mihaidusmanu/d2-net), on the numpy
# forward of the test model.

def resize_align_corners(x, h, w):
    c, hi, wi = x.shape
    ry = (hi - 1) / (h - 1) if h > 1 else 0.0
    rx = (wi - 1) / (w - 1) if w > 1 else 0.0
    sy = np.arange(h) * ry
    sx = np.arange(w) * rx
    y0 = np.minimum(np.floor(sy).astype(int), hi - 1)
    x0 = np.minimum(np.floor(sx).astype(int), wi - 1)
    y1 = np.minimum(y0 + 1, hi - 1)
    x1 = np.minimum(x0 + 1, wi - 1)
    fy = (sy - y0)[None, :, None]
    fx = (sx - x0)[None, None, :]
    top = (1 - fx) * x[:, y0][:, :, x0] + fx * x[:, y0][:, :, x1]
    bottom = (1 - fx) * x[:, y1][:, :, x0] + fx * x[:, y1][:, :, x1]
    return (1 - fy) * top + fy * bottom


def filt(d, f):
    """3x3 correlation of every channel with zero padding (conv2d, padding 1)."""
    c, h, w = d.shape
    p = np.pad(d, ((0, 0), (1, 1), (1, 1)))
    out = np.zeros_like(d)
    for i in range(3):
        for j in range(3):
            if f[i][j] != 0:
                out += f[i][j] * p[:, i:i + h, j:j + w]
    return out


DII = [[0, 1, 0], [0, -2, 0], [0, 1, 0]]
DJJ = [[0, 0, 0], [1, -2, 1], [0, 0, 0]]
DIJ = [[0.25, 0, -0.25], [0, 0, 0], [-0.25, 0, 0.25]]
DI = [[0, -0.5, 0], [0, 0, 0], [0, 0.5, 0]]
DJ = [[0, 0, 0], [-0.5, 0, 0.5], [0, 0, 0]]


def hard_detection(d, edge_threshold=5.0):
    is_depth_max = d == d.max(axis=0, keepdims=True)
    p = np.pad(d, ((0, 0), (1, 1), (1, 1)), constant_values=-np.inf)
    h, w = d.shape[1:]
    local_max = np.max([p[:, i:i + h, j:j + w] for i in range(3) for j in range(3)], axis=0)
    is_local_max = d == local_max
    dii, djj, dij = filt(d, DII), filt(d, DJJ), filt(d, DIJ)
    det = dii * djj - dij * dij
    tr = dii + djj
    threshold = (edge_threshold + 1) ** 2 / edge_threshold
    with np.errstate(divide="ignore", invalid="ignore"):
        is_not_edge = (tr * tr / det <= threshold) & (det > 0)
    return is_depth_max & is_local_max & is_not_edge


def localization(d):
    dx, dy = filt(d, DI), filt(d, DJ)
    dxx, dyy, dxy = filt(d, DII), filt(d, DJJ), filt(d, DIJ)
    with np.errstate(divide="ignore", invalid="ignore"):
        det = dxx * dyy - dxy * dxy
        step_i = -((dyy / det) * dx + (-dxy / det) * dy)
        step_j = -((-dxy / det) * dx + (dxx / det) * dy)
    return step_i, step_j


def soft_detection(d):
    b = np.maximum(d, 0)
    e = np.exp(b / b.max()) if b.max() > 0 else np.ones_like(b)
    h, w = d.shape[1:]
    p = np.pad(e, ((0, 0), (1, 1), (1, 1)), constant_values=1.0)
    sum_exp = np.sum([p[:, i:i + h, j:j + w] for i in range(3) for j in range(3)], axis=0)
    depth_max = b.max(axis=0, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        beta = np.where(depth_max > 0, b / depth_max, 0.0)
    score = (e / sum_exp * beta).max(axis=0)
    return score / score.sum()


def d2net_extract(p, image_rgb, scales, soft=False):
    """image_rgb: H x W x 3 uint8 (no max_edge resize here). Returns raw
    keypoints N x 3 (x, y, 1/scale), scores N, descriptors N x C."""
    mean = np.array([103.939, 116.779, 123.68])
    img = (image_rgb[:, :, ::-1].astype(np.float64) - mean).transpose(2, 0, 1)
    h_init, w_init = img.shape[1:]
    kps, scs, descs = [], [], []
    previous, banned = None, None
    for idx, scale in enumerate(scales):
        hl, wl = int(np.floor(h_init * scale)), int(np.floor(w_init * scale))
        cur = img if scale == 1 else resize_align_corners(img, hl, wl)
        d = forward("d2net", p, cur)
        h, w = d.shape[1:]
        if previous is not None:
            d = d + resize_align_corners(previous, h, w)
        det = hard_detection(d)
        if banned is not None:
            bh, bw = banned.shape
            si = np.minimum(np.floor(np.arange(h) * np.float32(bh / h)).astype(int), bh - 1)
            sj = np.minimum(np.floor(np.arange(w) * np.float32(bw / w)).astype(int), bw - 1)
            banned = banned[si][:, sj]
            det = det & ~banned[None]
            banned = det.any(axis=0) | banned
        else:
            banned = det.any(axis=0)
        ks, is_, js = np.nonzero(det)
        step_i, step_j = localization(d)
        di, dj = step_i[ks, is_, js], step_j[ks, is_, js]
        keep = (np.abs(di) < 0.5) & (np.abs(dj) < 0.5)
        ks, is_, js, di, dj = ks[keep], is_[keep], js[keep], di[keep], dj[keep]
        pi, pj = is_ + di, js + dj
        i0, j0 = np.floor(pi).astype(int), np.floor(pj).astype(int)
        i1, j1 = np.ceil(pi).astype(int), np.ceil(pj).astype(int)
        valid = (i0 >= 0) & (j0 >= 0) & (i1 < h) & (j1 < w)
        ks, is_, js, pi, pj = ks[valid], is_[valid], js[valid], pi[valid], pj[valid]
        i0, j0, i1, j1 = i0[valid], j0[valid], i1[valid], j1[valid]
        ti, tj = pi - i0, pj - j0
        desc = ((1 - ti) * (1 - tj) * d[:, i0, j0] + (1 - ti) * tj * d[:, i0, j1] +
                ti * (1 - tj) * d[:, i1, j0] + ti * tj * d[:, i1, j1])
        desc = desc / np.maximum(np.linalg.norm(desc, axis=0, keepdims=True), 1e-12)
        y = (4 * pi + 1.5) * h_init / hl
        x = (4 * pj + 1.5) * w_init / wl
        if soft:
            s = soft_detection(d)[is_, js]
        else:
            s = d[ks, is_, js] / (idx + 1)
        kps.append(np.stack([x, y, np.full_like(x, 1.0 / scale)], axis=1))
        scs.append(s)
        descs.append(desc.T)
        previous = d
    return np.concatenate(kps), np.concatenate(scs), np.concatenate(descs)


def main(argv):
    if len(argv) in (3, 5) and argv[1] == "make":
        import onnx
        global NETVLAD_H, NETVLAD_W
        if len(argv) == 5:
            NETVLAD_H, NETVLAD_W = int(argv[3]), int(argv[4])
        for name, p in specs().items():
            onnx.save(build_onnx(name, p), f"{argv[2]}/{name}.onnx")
            np.savez(f"{argv[2]}/{name}.npz", **p)
        return 0
    if len(argv) == 9 and argv[1] == "forward":
        name, d, src, c, h, w, dst = argv[2:9]
        p = dict(np.load(f"{d}/{name}.npz"))
        x = np.fromfile(src, dtype="<f4").reshape(int(c), int(h), int(w)).astype(np.float64)
        y = forward(name, p, x).astype("<f4")
        y.tofile(dst)
        print(" ".join(str(s) for s in y.shape))
        return 0
    if len(argv) == 9 and argv[1] == "d2net":
        d, src, h, w, scales, soft, prefix = argv[2:9]
        p = dict(np.load(f"{d}/d2net.npz"))
        img = np.fromfile(src, dtype=np.uint8).reshape(int(h), int(w), 3)
        k, s, ds = d2net_extract(p, img, [float(x) for x in scales.split(",")], soft == "soft")
        k.astype("<f4").tofile(prefix + ".kpt")
        s.astype("<f4").tofile(prefix + ".scores")
        ds.astype("<f4").tofile(prefix + ".desc")
        print(len(s))
        return 0
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))

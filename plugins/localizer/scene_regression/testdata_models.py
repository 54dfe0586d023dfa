#!/usr/bin/env python3
"""Small ONNX models with known outputs for the tests of localizer/posenet and
localizer/esac (python3-onnx + python3-numpy; no training framework).

  posenet DIR SEED                       random GAP -> Gemm heads (posenet.onnx, posenet.npz)
  posenet_forward DIR IN.f32 H W OUT.f32 numpy forward of posenet.onnx: 3 position + 4 orientation
  constant_pose FILE px py pz qw qx qy qz  outputs these numbers whatever the image
  expert FILE COORDS.f32 H W STRIDE      outputs the 1x3xHxW float32 scene coordinates of COORDS.f32
                                         (after an average pool of STRIDE: output size = input / STRIDE)
  gating FILE l0 l1 ...                  outputs these logits whatever the image

Inputs are named `image` (1x3xHxW float32, dynamic H, W); outputs `position`,
`orientation`, `coordinates`, `logits` (the contracts of plugins/localizer/scene_regression/README.md).
"""
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

OPSET = 11


def image_input():
    return helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, "H", "W"])


def save(nodes, inits, outputs, path):
    graph = helper.make_graph(nodes, "locforge_test", [image_input()], outputs, inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)])
    model.ir_version = 6  # OpenCV 4.6's reader
    onnx.checker.check_model(model)
    onnx.save(model, path)


def pose_heads(path, wp, bp, wq, bq):
    """GAP -> flatten -> two Gemm heads."""
    inits = [numpy_helper.from_array(a.astype(np.float32), n)
             for a, n in [(wp, "wp"), (bp, "bp"), (wq, "wq"), (bq, "bq")]]
    nodes = [helper.make_node("GlobalAveragePool", ["image"], ["pooled"]),
             helper.make_node("Flatten", ["pooled"], ["flat"], axis=1),
             helper.make_node("Gemm", ["flat", "wp", "bp"], ["position"], transB=1),
             helper.make_node("Gemm", ["flat", "wq", "bq"], ["orientation"], transB=1)]
    outs = [helper.make_tensor_value_info("position", TensorProto.FLOAT, [1, 3]),
            helper.make_tensor_value_info("orientation", TensorProto.FLOAT, [1, 4])]
    save(nodes, inits, outs, path)


def main(argv):
    cmd = argv[1]
    if cmd == "posenet":
        rng = np.random.default_rng(int(argv[3]))
        w = {"wp": rng.normal(size=(3, 3)), "bp": rng.normal(size=3) * 5,
             "wq": rng.normal(size=(4, 3)), "bq": np.array([1.0, 0.1, -0.2, 0.3]) + rng.normal(size=4) * 0.1}
        np.savez(argv[2] + "/posenet.npz", **w)
        pose_heads(argv[2] + "/posenet.onnx", w["wp"], w["bp"], w["wq"], w["bq"])
    elif cmd == "posenet_forward":
        w = np.load(argv[2] + "/posenet.npz")
        h, wd = int(argv[4]), int(argv[5])
        x = np.fromfile(argv[3], dtype=np.float32).reshape(3, h, wd).astype(np.float64)
        m = x.mean(axis=(1, 2))
        out = np.concatenate([w["wp"] @ m + w["bp"], w["wq"] @ m + w["bq"]]).astype(np.float32)
        out.tofile(argv[6])
    elif cmd == "constant_pose":
        v = np.array([float(a) for a in argv[3:10]])
        pose_heads(argv[2], np.zeros((3, 3)), v[:3], np.zeros((4, 3)), v[3:])
    elif cmd == "expert":
        h, w, stride = int(argv[4]), int(argv[5]), int(argv[6])
        coords = np.fromfile(argv[3], dtype=np.float32).reshape(1, 3, h, w)
        inits = [numpy_helper.from_array(np.zeros((1, 3, 1, 1), np.float32), "zero"),
                 numpy_helper.from_array(coords, "coords")]
        nodes = [helper.make_node("AveragePool", ["image"], ["pooled"], kernel_shape=[stride, stride],
                                  strides=[stride, stride]),
                 helper.make_node("Mul", ["pooled", "zero"], ["zeroed"]),
                 helper.make_node("Add", ["zeroed", "coords"], ["coordinates"])]
        outs = [helper.make_tensor_value_info("coordinates", TensorProto.FLOAT, [1, 3, h, w])]
        save(nodes, inits, outs, argv[2])
    elif cmd == "gating":
        logits = np.array([float(a) for a in argv[3:]], np.float32)
        inits = [numpy_helper.from_array(np.zeros((len(logits), 3), np.float32), "w"),
                 numpy_helper.from_array(logits, "b")]
        nodes = [helper.make_node("GlobalAveragePool", ["image"], ["pooled"]),
                 helper.make_node("Flatten", ["pooled"], ["flat"], axis=1),
                 helper.make_node("Gemm", ["flat", "w", "b"], ["logits"], transB=1)]
        outs = [helper.make_tensor_value_info("logits", TensorProto.FLOAT, [1, len(logits)])]
        save(nodes, inits, outs, argv[2])
    else:
        sys.exit("unknown command " + cmd)


if __name__ == "__main__":
    main(sys.argv)

#!/usr/bin/env python3
"""A person-segmentation ONNX model with a known output for the tests of
analysis/person_segmentation (python3-onnx): person probability =
sigmoid(5 x red channel), averaged over 4x4 cells (output stride 4), i.e.
~1 where the image is saturated red, ~0 where it has no red.

  segmentation_model.py FILE
"""
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

w = np.zeros((1, 3, 1, 1), np.float32)
w[0, 0] = 5.0
graph = helper.make_graph(
    [helper.make_node("Conv", ["image", "w"], ["red"], kernel_shape=[1, 1]),
     helper.make_node("AveragePool", ["red"], ["pooled"], kernel_shape=[4, 4], strides=[4, 4]),
     helper.make_node("Sigmoid", ["pooled"], ["person"])],
    "locforge_test_segmentation",
    [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, "H", "W"])],
    [helper.make_tensor_value_info("person", TensorProto.FLOAT, [1, 1, "h", "w"])],
    [numpy_helper.from_array(w, "w")])
model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 11)])
model.ir_version = 6  # OpenCV 4.6's reader
onnx.checker.check_model(model)
onnx.save(model, sys.argv[1])

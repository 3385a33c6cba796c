#!/usr/bin/python3
"""make_fuzz_seeds.py - the seed corpus of tests/fuzz/fuzz_onnx.c: tiny ONNX models (a few hundred
bytes each) covering the importer's paths: conv + relu, a Shape/Gather/Concat/Reshape chain,
Resize with sizes, MatMul + bias + Softmax, LayerNormalization, Slice/Transpose/Pad.
    /usr/bin/python3 tests/nn/make_fuzz_seeds.py tests/fuzz/corpus/onnx
"""
import os
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper


def save(out, name, nodes, inputs, outputs, inits):
    g = helper.make_graph(nodes, name, inputs, outputs, inits)
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 17)])
    m.ir_version = 8

    onnx.save(m, os.path.join(out, name + ".onnx"))


def vi(name, shape):
    return helper.make_tensor_value_info(name, TensorProto.FLOAT, shape)


def main(out):
    os.makedirs(out, exist_ok=True)
    r = np.random.default_rng(0)
    f = lambda *s: r.standard_normal(s).astype(np.float32)
    i64 = lambda v: np.array(v, np.int64)
    save(out, "conv_relu", [helper.make_node("Conv", ["x", "w", "b"], ["c"], pads=[1, 1, 1, 1], strides=[2, 2], group=1),
                            helper.make_node("Relu", ["c"], ["y"])],
         [vi("x", [1, 2, 5, 5])], [vi("y", None)], [numpy_helper.from_array(f(3, 2, 3, 3), "w"), numpy_helper.from_array(f(3), "b")])
    save(out, "shape_chain", [helper.make_node("Shape", ["x"], ["s"]),
                              helper.make_node("Gather", ["s", "i0"], ["g"], axis=0),
                              helper.make_node("Unsqueeze", ["g", "ax"], ["u"]),
                              helper.make_node("Concat", ["u", "m1"], ["shape"], axis=0),
                              helper.make_node("Reshape", ["x", "shape"], ["y"])],
         [vi("x", [2, 3, 4])], [vi("y", None)],
         [numpy_helper.from_array(i64(0), "i0"), numpy_helper.from_array(i64([0]), "ax"), numpy_helper.from_array(i64([-1]), "m1")])
    save(out, "resize", [helper.make_node("Resize", ["x", "", "", "sizes"], ["y"], mode="linear",
                                          coordinate_transformation_mode="align_corners")],
         [vi("x", [1, 1, 3, 4])], [vi("y", None)], [numpy_helper.from_array(i64([1, 1, 5, 7]), "sizes")])
    save(out, "matmul_softmax", [helper.make_node("MatMul", ["x", "w"], ["m"]), helper.make_node("Add", ["b", "m"], ["a"]),
                                 helper.make_node("Softmax", ["a"], ["y"], axis=-1)],
         [vi("x", [2, 3, 4])], [vi("y", None)], [numpy_helper.from_array(f(4, 5), "w"), numpy_helper.from_array(f(5), "b")])
    save(out, "layernorm", [helper.make_node("LayerNormalization", ["x", "g", "b"], ["y"], axis=-1, epsilon=1e-6)],
         [vi("x", [2, 6])], [vi("y", None)], [numpy_helper.from_array(f(6), "g"), numpy_helper.from_array(f(6), "b")])
    save(out, "slice_pad", [helper.make_node("Slice", ["x", "st", "en", "axs", "stp"], ["s"]),
                            helper.make_node("Transpose", ["s"], ["t"], perm=[0, 1, 3, 2]),
                            helper.make_node("Pad", ["t", "pads"], ["y"], mode="reflect")],
         [vi("x", [1, 2, 6, 6])], [vi("y", None)],
         [numpy_helper.from_array(i64([1, 0]), "st"), numpy_helper.from_array(i64([6, 5]), "en"),
          numpy_helper.from_array(i64([2, 3]), "axs"), numpy_helper.from_array(i64([2, 1]), "stp"),
          numpy_helper.from_array(i64([0, 0, 1, 1, 0, 0, 1, 1]), "pads")])
    save(out, "convtranspose_gelu", [helper.make_node("ConvTranspose", ["x", "w"], ["c"], strides=[2, 2]),
                                     helper.make_node("Div", ["c", "sq2"], ["d"]), helper.make_node("Erf", ["d"], ["e"]),
                                     helper.make_node("Add", ["e", "one"], ["a"]), helper.make_node("Mul", ["c", "a"], ["m"]),
                                     helper.make_node("Mul", ["m", "half"], ["y"])],
         [vi("x", [1, 2, 3, 3])], [vi("y", None)],
         [numpy_helper.from_array(f(2, 3, 2, 2), "w"), numpy_helper.from_array(np.float32(1.4142135), "sq2"),
          numpy_helper.from_array(np.float32(1.0), "one"), numpy_helper.from_array(np.float32(0.5), "half")])


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "tests/fuzz/corpus/onnx")

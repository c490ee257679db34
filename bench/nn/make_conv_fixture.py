#!/usr/bin/env python3
"""Write the conv/pool/residual fixture of samara-nn's graph import test and its expected
outputs computed by onnxruntime (an independent runtime).

  crates/samara-nn/tests/data/conv_residual.onnx      (a few KB, opset 13)
  crates/samara-nn/tests/data/conv_residual.csv       (input entries then outputs, one
                                                       sample a row, float32 inputs)

The network (input [1, 2, 6, 6]):
  Conv 2->3 (3x3, pad 1) -> BatchNormalization -> Relu = a
  Conv 3->3 (3x3, pad 1) on a -> Relu -> Conv 3->3 (1x1, no bias) = c
  bn + c + a (two skip connections around the branch's Relu: bn signed, a
  non-negative) -> Relu
  MaxPool 2x2 stride 2 -> [1, 3, 3, 3]
  Pad 1 (constant 0) -> AveragePool 2x2 stride 1 -> [1, 3, 4, 4]
  Flatten -> Gemm (transB) 48 -> 5 -> LeakyRelu(0.1)
  Reshape [5, 1] -> MatMul(W [3, 5], x) (the weight on the left) -> Reshape [1, 3]

usage: python bench/nn/make_conv_fixture.py   (needs onnx, onnxruntime, numpy)
"""
import os

import numpy as np
import onnx
import onnxruntime as ort
from onnx import TensorProto, helper, numpy_helper

ROOT = os.path.join(os.path.dirname(__file__), "..", "..", "crates", "samara-nn", "tests", "data")
rng = np.random.default_rng(37)


def init(name, shape, scale=0.5):
    return numpy_helper.from_array((rng.standard_normal(shape) * scale).astype(np.float32), name)


def main():
    inits = [
        init("w1", (3, 2, 3, 3)), init("b1", (3,), 0.1),
        numpy_helper.from_array(rng.uniform(0.5, 1.5, 3).astype(np.float32), "bn_s"),
        init("bn_b", (3,), 0.1), init("bn_m", (3,), 0.1),
        numpy_helper.from_array(rng.uniform(0.5, 1.5, 3).astype(np.float32), "bn_v"),
        init("w2", (3, 3, 3, 3), 0.3), init("b2", (3,), 0.1), init("w3", (3, 3, 1, 1)),
        numpy_helper.from_array(np.array([0, 0, 1, 1, 0, 0, 1, 1], dtype=np.int64), "pads"),
        init("wg", (5, 48), 0.3), init("bg", (5,), 0.1),
        numpy_helper.from_array(np.array([5, 1], dtype=np.int64), "s51"),
        init("wl", (3, 5)),
        numpy_helper.from_array(np.array([1, 3], dtype=np.int64), "s13"),
    ]
    nodes = [
        helper.make_node("Conv", ["x", "w1", "b1"], ["c1"], name="conv1", pads=[1, 1, 1, 1], kernel_shape=[3, 3]),
        helper.make_node("BatchNormalization", ["c1", "bn_s", "bn_b", "bn_m", "bn_v"], ["bn"], name="bn1", epsilon=1e-3),
        helper.make_node("Relu", ["bn"], ["a"], name="relu1"),
        helper.make_node("Conv", ["a", "w2", "b2"], ["c2"], name="conv2", pads=[1, 1, 1, 1], strides=[1, 1], dilations=[1, 1]),
        helper.make_node("Relu", ["c2"], ["rb"], name="relu_branch"),
        helper.make_node("Conv", ["rb", "w3"], ["c3"], name="conv3", kernel_shape=[1, 1]),
        helper.make_node("Add", ["bn", "c3"], ["res0"], name="skip_signed"),
        helper.make_node("Add", ["res0", "a"], ["res"], name="skip_relu"),
        helper.make_node("Relu", ["res"], ["r2"], name="relu2"),
        helper.make_node("MaxPool", ["r2"], ["mp"], name="maxpool", kernel_shape=[2, 2], strides=[2, 2]),
        helper.make_node("Pad", ["mp", "pads"], ["pd"], name="pad", mode="constant"),
        helper.make_node("AveragePool", ["pd"], ["ap"], name="avgpool", kernel_shape=[2, 2], strides=[1, 1]),
        helper.make_node("Flatten", ["ap"], ["fl"], name="flatten", axis=1),
        helper.make_node("Gemm", ["fl", "wg", "bg"], ["g"], name="gemm", transB=1),
        helper.make_node("LeakyRelu", ["g"], ["lr"], name="leaky", alpha=0.1),
        helper.make_node("Reshape", ["lr", "s51"], ["col"], name="to_column"),
        helper.make_node("MatMul", ["wl", "col"], ["mm"], name="weight_left"),
        helper.make_node("Reshape", ["mm", "s13"], ["y"], name="to_row"),
    ]
    graph = helper.make_graph(
        nodes, "conv_residual",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 2, 6, 6])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 3])],
        inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)], producer_name="make_conv_fixture.py")
    model.ir_version = 8
    onnx.checker.check_model(model)
    path = os.path.join(ROOT, "conv_residual.onnx")
    onnx.save(model, path)
    sess = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    rows = []
    for _ in range(30):
        x = rng.uniform(-1, 1, (1, 2, 6, 6)).astype(np.float32)
        y = sess.run(None, {"x": x})[0].reshape(-1)
        rows.append(",".join(f"{v:.9g}" for v in list(x.reshape(-1)) + list(y)))
    with open(os.path.join(ROOT, "conv_residual.csv"), "w") as f:
        f.write("# bench/nn/make_conv_fixture.py: 72 inputs (x[1,2,6,6] row-major, float32) then 3 outputs, onnxruntime "
                + ort.__version__ + "\n")
        f.write("\n".join(rows) + "\n")
    print(path, os.path.getsize(path), "bytes")
    ops_mix()


def ops_mix():
    """The second fixture, ops_mix.onnx (input [1, 2, 4, 4], signed values): the
    remaining operators, each where its lowering is least trivial.
      MaxPool 3x3 stride 1 pad 1 on the signed input (windows of 4, 6 and 9 entries) = m
      ConvTranspose 2->2 (2x2, stride 2, pad 1) on m = t [1, 2, 6, 6]
      Slice t[:, :, 1:5, 0:6:2] = s [1, 2, 4, 3]; Transpose (0, 1, 3, 2) -> [1, 2, 3, 4]
      Gather(x, [1, 0], axis 1) (channels swapped), Slice [:, :, 1:4, :] -> [1, 2, 3, 4]
      Concat of the two along the channels -> [1, 4, 3, 4]
      PRelu (per-channel slopes 0.2, -0.3, 0.5, 0), Clip [-0.5, 0.7]
      Split into two [1, 2, 3, 4] halves, Sub, Identity, GlobalAveragePool -> [1, 2, 1, 1]
      Squeeze, Unsqueeze, Flatten -> [1, 2], Gemm(W, x) with transA and transB (the
      weight first) -> [4, 1], Flatten(axis 0) -> y [1, 4]
    """
    inits = [
        init("wt", (2, 2, 2, 2)), init("bt", (2,), 0.1),
        numpy_helper.from_array(np.array([0, 0, 1, 0], dtype=np.int64), "st"),
        numpy_helper.from_array(np.array([1, 2, 5, 6], dtype=np.int64), "en"),
        numpy_helper.from_array(np.array([0, 1, 2, 3], dtype=np.int64), "ax"),
        numpy_helper.from_array(np.array([1, 1, 1, 2], dtype=np.int64), "sp"),
        numpy_helper.from_array(np.array([1, 0], dtype=np.int64), "gi"),
        numpy_helper.from_array(np.array([0, 0, 1, 0], dtype=np.int64), "st2"),
        numpy_helper.from_array(np.array([1, 2, 4, 4], dtype=np.int64), "en2"),
        numpy_helper.from_array(np.array([[[0.2]], [[-0.3]], [[0.5]], [[0.0]]], dtype=np.float32), "slope"),
        numpy_helper.from_array(np.array(-0.5, dtype=np.float32), "lo"),
        numpy_helper.from_array(np.array(0.7, dtype=np.float32), "hi"),
        numpy_helper.from_array(np.array([2, 2], dtype=np.int64), "parts"),
        numpy_helper.from_array(np.array([2, 3], dtype=np.int64), "sq_axes"),
        numpy_helper.from_array(np.array([0], dtype=np.int64), "usq_axes"),
        init("wg", (2, 4)),
    ]
    n = helper.make_node
    nodes = [
        n("MaxPool", ["x"], ["m"], name="maxpool_signed", kernel_shape=[3, 3], strides=[1, 1], pads=[1, 1, 1, 1]),
        n("ConvTranspose", ["m", "wt", "bt"], ["t"], name="convT", strides=[2, 2], pads=[1, 1, 1, 1]),
        n("Slice", ["t", "st", "en", "ax", "sp"], ["s"], name="slice"),
        n("Transpose", ["s"], ["tr"], name="transpose", perm=[0, 1, 3, 2]),
        n("Gather", ["x", "gi"], ["gx"], name="gather", axis=1),
        n("Slice", ["gx", "st2", "en2"], ["gs"], name="slice2"),
        n("Concat", ["tr", "gs"], ["cat"], name="concat", axis=1),
        n("PRelu", ["cat", "slope"], ["pr"], name="prelu"),
        n("Clip", ["pr", "lo", "hi"], ["cl"], name="clip"),
        n("Split", ["cl", "parts"], ["p1", "p2"], name="split", axis=1),
        n("Sub", ["p1", "p2"], ["d"], name="sub"),
        n("Identity", ["d"], ["dm"], name="identity"),
        n("GlobalAveragePool", ["dm"], ["gap"], name="gap"),
        n("Squeeze", ["gap", "sq_axes"], ["sq"], name="squeeze"),
        n("Unsqueeze", ["sq", "usq_axes"], ["us"], name="unsqueeze"),
        n("Flatten", ["us"], ["fl"], name="flatten", axis=1),
        n("Gemm", ["wg", "fl"], ["gy"], name="gemm_weight_first", transA=1, transB=1),
        n("Flatten", ["gy"], ["y"], name="flatten_out", axis=0),
    ]
    graph = helper.make_graph(
        nodes, "ops_mix",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 2, 4, 4])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 4])],
        inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)], producer_name="make_conv_fixture.py")
    model.ir_version = 8
    onnx.checker.check_model(model)
    path = os.path.join(ROOT, "ops_mix.onnx")
    onnx.save(model, path)
    sess = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    rows = []
    for _ in range(30):
        x = rng.uniform(-1, 1, (1, 2, 4, 4)).astype(np.float32)
        y = sess.run(None, {"x": x})[0].reshape(-1)
        rows.append(",".join(f"{v:.9g}" for v in list(x.reshape(-1)) + list(y)))
    with open(os.path.join(ROOT, "ops_mix.csv"), "w") as f:
        f.write("# bench/nn/make_conv_fixture.py: 32 inputs (x[1,2,4,4] row-major, float32) then "
                + str(len(y)) + " outputs, onnxruntime " + ort.__version__ + "\n")
        f.write("\n".join(rows) + "\n")
    print(path, os.path.getsize(path), "bytes,", len(y), "outputs")


if __name__ == "__main__":
    main()

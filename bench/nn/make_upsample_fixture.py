#!/usr/bin/env python3
"""Write two samara-nn fixtures of the VNN-COMP 2023/2024 networks and their expected
outputs computed by onnxruntime (an independent runtime):

  crates/samara-nn/tests/data/upsample.onnx   (opset 9, scales as a constant input)
  crates/samara-nn/tests/data/upsample.csv    (18 inputs then 4 outputs per row)
  crates/samara-nn/tests/data/skip_slice.onnx (opset 14; 2024 linearizenn's layout)
  crates/samara-nn/tests/data/skip_slice.csv  (4 inputs then 2 outputs per row)

The network (input [1, 2, 3, 3], signed values):
  Upsample nearest, scales [1, 1, 2, 2] -> [1, 2, 6, 6]
  Conv 2->2 (3x3, pad 1) -> Relu
  Upsample nearest, scales [1, 1, 1.5, 2.5] (non-integer: floor(o / s)) -> [1, 2, 9, 15]
  Flatten -> Gemm (transB) 270 -> 4

skip_slice (input [1, 4]): Gemm 4->6 -> Relu -> Gemm 6->2 -> MatMul [2, 1] = a;
  Slice(input, starts [2], ends [INT64_MAX], axes [1], steps [1]) (PyTorch's x[:, 2:])
  -> MatMul [2, 1] = b; Concat(a, b, axis 1) -> MatMul [2, 2] -> y [1, 2]

usage: python bench/nn/make_upsample_fixture.py   (needs onnx, onnxruntime, numpy)
"""
import os

import numpy as np
import onnx
import onnxruntime as ort
from onnx import TensorProto, helper, numpy_helper

ROOT = os.path.join(os.path.dirname(__file__), "..", "..", "crates", "samara-nn", "tests", "data")
rng = np.random.default_rng(2023)


def write(nodes, inits, name, in_shape, out_shape, opset, ir, what):
    """Save the model as tests/data/NAME.onnx and 30 rows of inputs in [-1, 1] and
    onnxruntime's outputs as NAME.csv."""
    graph = helper.make_graph(
        nodes, name,
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, in_shape)],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, out_shape)],
        inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", opset)], producer_name="make_upsample_fixture.py")
    model.ir_version = ir
    onnx.checker.check_model(model)
    path = os.path.join(ROOT, name + ".onnx")
    onnx.save(model, path)
    sess = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    rows = []
    for _ in range(30):
        x = rng.uniform(-1, 1, in_shape).astype(np.float32)
        y = sess.run(None, {"x": x})[0].reshape(-1)
        rows.append(",".join(f"{v:.9g}" for v in list(x.reshape(-1)) + list(y)))
    with open(os.path.join(ROOT, name + ".csv"), "w") as f:
        f.write(f"# bench/nn/make_upsample_fixture.py: {what}, onnxruntime {ort.__version__}\n")
        f.write("\n".join(rows) + "\n")
    print(path, os.path.getsize(path), "bytes")


def main():
    f32 = lambda a, name: numpy_helper.from_array(np.asarray(a, dtype=np.float32), name)
    inits = [
        f32([1, 1, 2, 2], "s1"),
        f32(rng.standard_normal((2, 2, 3, 3)) * 0.5, "w"),
        f32(rng.standard_normal(2) * 0.1, "b"),
        f32([1, 1, 1.5, 2.5], "s2"),
        f32(rng.standard_normal((4, 270)) * 0.1, "wg"),
        f32(rng.standard_normal(4) * 0.1, "bg"),
    ]
    n = helper.make_node
    nodes = [
        n("Upsample", ["x", "s1"], ["u1"], name="up_int", mode="nearest"),
        n("Conv", ["u1", "w", "b"], ["c"], name="conv", pads=[1, 1, 1, 1], kernel_shape=[3, 3]),
        n("Relu", ["c"], ["r"], name="relu"),
        n("Upsample", ["r", "s2"], ["u2"], name="up_frac", mode="nearest"),
        n("Flatten", ["u2"], ["f"], name="flatten", axis=1),
        n("Gemm", ["f", "wg", "bg"], ["y"], name="gemm", transB=1),
    ]
    write(nodes, inits, "upsample", [1, 2, 3, 3], [1, 4], opset=9, ir=4,
          what="18 inputs (x[1,2,3,3] row-major, float32) then 4 outputs")
    skip_slice()


def skip_slice():
    f32 = lambda a, name: numpy_helper.from_array(np.asarray(a, dtype=np.float32), name)
    i64 = lambda a, name: numpy_helper.from_array(np.asarray(a, dtype=np.int64), name)
    inits = [
        f32(rng.standard_normal((6, 4)), "w1"), f32(rng.standard_normal(6) * 0.1, "b1"),
        f32(rng.standard_normal((2, 6)), "w2"), f32(rng.standard_normal(2) * 0.1, "b2"),
        f32(rng.standard_normal((2, 1)), "wc"), f32(rng.standard_normal((2, 1)), "wl"),
        f32(rng.standard_normal((2, 2)), "wo"),
        i64([2], "st"), i64([np.iinfo(np.int64).max], "en"), i64([1], "ax"), i64([1], "sp"),
    ]
    n = helper.make_node
    nodes = [
        n("Gemm", ["x", "w1", "b1"], ["g1"], name="gemm1", transB=1),
        n("Relu", ["g1"], ["r1"], name="relu1"),
        n("Gemm", ["r1", "w2", "b2"], ["g2"], name="gemm2", transB=1),
        n("MatMul", ["g2", "wc"], ["a"], name="controller"),
        n("Slice", ["x", "st", "en", "ax", "sp"], ["s"], name="slice_to_int64_max"),
        n("MatMul", ["s", "wl"], ["b"], name="linear_weight"),
        n("Concat", ["a", "b"], ["c"], name="concat", axis=1),
        n("MatMul", ["c", "wo"], ["y"], name="linear_constraint"),
    ]
    write(nodes, inits, "skip_slice", [1, 4], [1, 2], opset=14, ir=8,
          what="4 inputs (x[1,4], float32) then 2 outputs")


if __name__ == "__main__":
    main()

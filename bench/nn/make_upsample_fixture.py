#!/usr/bin/env python3
"""Write samara-nn's Upsample fixture (issue 37: VNN-COMP 2023 cgan's upsampling
generator) and its expected outputs computed by onnxruntime (an independent runtime).

  crates/samara-nn/tests/data/upsample.onnx   (opset 9, scales as a constant input)
  crates/samara-nn/tests/data/upsample.csv    (18 inputs then 4 outputs per row)

The network (input [1, 2, 3, 3], signed values):
  Upsample nearest, scales [1, 1, 2, 2] -> [1, 2, 6, 6]
  Conv 2->2 (3x3, pad 1) -> Relu
  Upsample nearest, scales [1, 1, 1.5, 2.5] (non-integer: floor(o / s)) -> [1, 2, 9, 15]
  Flatten -> Gemm (transB) 270 -> 4

usage: python bench/nn/make_upsample_fixture.py   (needs onnx, onnxruntime, numpy)
"""
import os

import numpy as np
import onnx
import onnxruntime as ort
from onnx import TensorProto, helper, numpy_helper

ROOT = os.path.join(os.path.dirname(__file__), "..", "..", "crates", "samara-nn", "tests", "data")
rng = np.random.default_rng(2023)


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
    graph = helper.make_graph(
        nodes, "upsample",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 2, 3, 3])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 4])],
        inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 9)], producer_name="make_upsample_fixture.py")
    model.ir_version = 4
    onnx.checker.check_model(model)
    path = os.path.join(ROOT, "upsample.onnx")
    onnx.save(model, path)
    sess = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    rows = []
    for _ in range(30):
        x = rng.uniform(-1, 1, (1, 2, 3, 3)).astype(np.float32)
        y = sess.run(None, {"x": x})[0].reshape(-1)
        rows.append(",".join(f"{v:.9g}" for v in list(x.reshape(-1)) + list(y)))
    with open(os.path.join(ROOT, "upsample.csv"), "w") as f:
        f.write("# bench/nn/make_upsample_fixture.py: 18 inputs (x[1,2,3,3] row-major, float32) then 4 outputs, onnxruntime "
                + ort.__version__ + "\n")
        f.write("\n".join(rows) + "\n")
    print(path, os.path.getsize(path), "bytes")


if __name__ == "__main__":
    main()

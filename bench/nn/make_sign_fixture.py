#!/usr/bin/env python3
"""Write a samara-nn fixture in the layout of VNN-COMP 2023's traffic_signs_recognition
networks (binarised, Larq-exported) and its expected outputs computed by onnxruntime (an
independent runtime):

  crates/samara-nn/tests/data/sign_bnn.onnx  (opset 15)
  crates/samara-nn/tests/data/sign_bnn.csv   (32 inputs then 5 outputs per row)

The network (input [1, 4, 4, 2], NHWC as Larq exports it):
  Transpose to NCHW -> Conv 2->3 (2x2, weights +-1, no bias) -> Transpose to NHWC
  -> Sign -> Add 0.1 -> Sign (Larq's ste_sign: sign(sign(x) + 0.1), so 0 -> 1)
  -> Reshape [-1, 27] -> Sign -> Add 0.1 -> Sign -> MatMul [27, 5] (+-1) -> Softmax

Rows: 15 with integer inputs in [-2, 2] (so Sign meets exact zeros, Sign(0) = 0, and the
logits tie), 15 with uniform inputs in [-1, 1].

usage: python bench/nn/make_sign_fixture.py   (needs onnx, onnxruntime, numpy)
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
    i64 = lambda a, name: numpy_helper.from_array(np.asarray(a, dtype=np.int64), name)
    pm = lambda shape: rng.choice([-1.0, 1.0], size=shape)
    inits = [
        f32(pm((3, 2, 2, 2)), "wc"),
        f32(0.1, "tenth"),
        i64([-1, 27], "shape"),
        f32(pm((27, 5)), "wd"),
    ]
    n = helper.make_node
    nodes = [
        n("Transpose", ["x"], ["xt"], name="to_nchw", perm=[0, 3, 1, 2]),
        n("Conv", ["xt", "wc"], ["c"], name="qconv", kernel_shape=[2, 2], strides=[1, 1], dilations=[1, 1], group=1),
        n("Transpose", ["c"], ["ct"], name="to_nhwc", perm=[0, 2, 3, 1]),
        n("Sign", ["ct"], ["s1"], name="ste_sign_1/Sign"),
        n("Add", ["s1", "tenth"], ["a1"], name="ste_sign_1/add"),
        n("Sign", ["a1"], ["s2"], name="ste_sign_1/Sign_1"),
        n("Reshape", ["s2", "shape"], ["f"], name="flatten"),
        n("Sign", ["f"], ["s3"], name="ste_sign_2/Sign"),
        n("Add", ["s3", "tenth"], ["a3"], name="ste_sign_2/add"),
        n("Sign", ["a3"], ["s4"], name="ste_sign_2/Sign_1"),
        n("MatMul", ["s4", "wd"], ["logits"], name="qdense"),
        n("Softmax", ["logits"], ["y"], name="softmax"),
    ]
    graph = helper.make_graph(
        nodes, "sign_bnn",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["batch", 4, 4, 2])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["batch", 5])],
        inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 15)], producer_name="make_sign_fixture.py")
    model.ir_version = 8
    onnx.checker.check_model(model)
    path = os.path.join(ROOT, "sign_bnn.onnx")
    onnx.save(model, path)
    sess = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    rows = []
    for k in range(30):
        if k < 15:
            x = rng.integers(-2, 3, (1, 4, 4, 2)).astype(np.float32)
        else:
            x = rng.uniform(-1, 1, (1, 4, 4, 2)).astype(np.float32)
        y = sess.run(None, {"x": x})[0].reshape(-1)
        rows.append(",".join(f"{v:.9g}" for v in list(x.reshape(-1)) + list(y)))
    with open(os.path.join(ROOT, "sign_bnn.csv"), "w") as f:
        f.write(f"# bench/nn/make_sign_fixture.py: 32 inputs (x[1,4,4,2] row-major, float32) then 5 outputs (softmax), onnxruntime {ort.__version__}\n")
        f.write("\n".join(rows) + "\n")
    print(path, os.path.getsize(path), "bytes")


if __name__ == "__main__":
    main()

"""Cross-check samara's verdicts against Marabou on random queries (issue: verifier).

Each query: a random ReLU network (3-6 inputs, two hidden layers, 1-2 outputs; ONNX
Gemm/Relu, float32), a random input box in [-1, 1]^n, and a random linear output
constraint `a.Y >= c` with c near the median of sampled values, so that both outcomes
occur. The same VNN-LIB file goes to `samara verify-vnnlib` and, as constraints, to
Marabou. Disagreements (sat vs unsat) are counted; every samara `sat` is re-evaluated
with onnxruntime.

Usage: bench/.venv/bin/python bench/verify/marabou_crosscheck.py [--n 500]
"""
import argparse
import json
import os
import subprocess
import tempfile
import time

import numpy as np
import onnx
import onnxruntime as ort
from onnx import TensorProto, helper, numpy_helper

here = os.path.dirname(os.path.abspath(__file__))
repo = os.path.dirname(os.path.dirname(here))
ap = argparse.ArgumentParser()
ap.add_argument("--n", type=int, default=500)
args = ap.parse_args()
subprocess.run(["cargo", "build", "--release", "-q", "-p", "samara-cli"], cwd=repo, check=True)
samara = os.path.join(repo, "target", "release", "samara")
from maraboupy import Marabou  # noqa: E402

rng = np.random.default_rng(7)
tmp = tempfile.mkdtemp()


def make_net(path, dims):
    nodes, inits, prev = [], [], "x"
    for k in range(len(dims) - 1):
        W = rng.normal(0, 1.0 / np.sqrt(dims[k]), (dims[k], dims[k + 1])).astype(np.float32)
        b = rng.normal(0, 0.3, dims[k + 1]).astype(np.float32)
        inits += [numpy_helper.from_array(W, f"W{k}"), numpy_helper.from_array(b, f"b{k}")]
        out = f"z{k}" if k < len(dims) - 2 else "y"
        nodes.append(helper.make_node("Gemm", [prev, f"W{k}", f"b{k}"], [out]))
        if k < len(dims) - 2:
            nodes.append(helper.make_node("Relu", [out], [f"a{k}"]))
            prev = f"a{k}"
    g = helper.make_graph(nodes, "rand", [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["N", dims[0]])],
                          [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["N", dims[-1]])], inits)
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 13)])
    m.ir_version = 7
    onnx.save(m, path)


stats = {"agree": 0, "disagree": 0, "samara_unknown": 0, "marabou_unknown": 0, "sat": 0, "unsat": 0, "bad_cex": 0}
t_samara = t_marabou = 0.0
for i in range(args.n):
    n_in = int(rng.integers(3, 7))
    dims = [n_in, int(rng.integers(6, 13)), int(rng.integers(4, 9)), int(rng.integers(1, 3))]
    net_path = os.path.join(tmp, f"n{i}.onnx")
    make_net(net_path, dims)
    lo = [float(v) for v in rng.uniform(-1, 0, n_in)]
    hi = [float(l + w) for l, w in zip(lo, rng.uniform(0.05, 1.0, n_in))]
    a = [float(v) for v in rng.normal(size=dims[-1])]
    lo, hi, a = np.array(lo), np.array(hi), np.array(a)
    sess = ort.InferenceSession(net_path, providers=["CPUExecutionProvider"])
    xs = rng.uniform(lo, hi, (2000, n_in)).astype(np.float32)
    ys = sess.run(None, {"x": xs})[0].astype(np.float64)
    vals = ys @ a
    c = float(np.quantile(vals, rng.uniform(0.9, 1.0)) + rng.normal(0, 0.05))
    lines = [f"(declare-const X_{k} Real)" for k in range(n_in)] + [f"(declare-const Y_{k} Real)" for k in range(dims[-1])]
    lines += [f"(assert (>= X_{k} {float(lo[k])!r}))" for k in range(n_in)] + [f"(assert (<= X_{k} {float(hi[k])!r}))" for k in range(n_in)]
    terms = " ".join(f"(* {float(a[k])!r} Y_{k})" if a[k] >= 0 else f"(* (- {float(-a[k])!r}) Y_{k})" for k in range(dims[-1]))
    lines.append(f"(assert (or (and (>= (+ {terms}) {c!r}))))" if c >= 0 else f"(assert (or (and (>= (+ {terms}) (- {-c!r})))))")
    prop = os.path.join(tmp, f"p{i}.vnnlib")
    with open(prop, "w") as f:
        f.write("\n".join(lines) + "\n")
    t = time.perf_counter()
    out = subprocess.run([samara, "verify-vnnlib", "--network", net_path, "--property", prop, "--json", "--timeout", "60"],
                         capture_output=True, text=True)
    t_samara += time.perf_counter() - t
    res = json.loads(out.stdout)
    s = res["result"]
    if s == "sat":
        x = np.array(res["counterexample"]["inputs"], dtype=np.float32)
        y = sess.run(None, {"x": x.reshape(1, -1)})[0].ravel().astype(np.float64)
        # float32 runtime vs f64 evaluation: allow 1e-5 relative on the constraint.
        if not (np.all(x >= lo.astype(np.float32) - 1e-7) and np.all(x <= hi.astype(np.float32) + 1e-7) and y @ a >= c - 1e-5 * (1 + abs(c))):
            stats["bad_cex"] += 1
    t = time.perf_counter()
    net = Marabou.read_onnx(net_path)
    iv, ov = net.inputVars[0].flatten(), net.outputVars[0].flatten()
    for k in range(n_in):
        net.setLowerBound(iv[k], float(lo[k]))
        net.setUpperBound(iv[k], float(hi[k]))
    net.addInequality(list(ov), list(-a), -c)  # -a.Y <= -c
    m = net.solve(options=Marabou.createOptions(verbosity=0, timeoutInSeconds=60), verbose=False)[0]
    t_marabou += time.perf_counter() - t
    if s == "unknown":
        stats["samara_unknown"] += 1
    elif m not in ("sat", "unsat"):
        stats["marabou_unknown"] += 1
    elif s == m:
        stats["agree"] += 1
        stats[s] += 1
    else:
        stats["disagree"] += 1
        print(f"DISAGREEMENT on query {i}: samara {s}, Marabou {m} ({net_path}, {prop})")
print(json.dumps(stats))
print(f"{args.n} queries: samara {t_samara:.2f} s (process per query), Marabou {t_marabou:.2f} s")

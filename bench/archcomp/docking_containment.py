#!/usr/bin/env python3
"""Spacecraft docking: simulated flights inside the sets of a `samara reach` run.

An independent check of a docking proof (bench/archcomp/results.md, 2026-11-27, "docking
decided on a grid"): reads OUT/reach.json of `samara reach --system
examples/archcomp/spacecraft_docking.sys --network Docking/model.onnx ... --out OUT`,
draws flights from random points of every sub-box of the initial set (the box's corners
and uniform points), flies them with benchmarks/Docking/dynamics.m in numpy (classic RK4,
100 steps per 1 s period, the control held over the period) and the network evaluated in
float64 from the ONNX weights (checked against onnxruntime when it is installed), and
checks that the state at every whole second lies in that sub-box's set of that instant
(up to TOL, for the float32 weights' products and the integrator's error), and that
every flight keeps the speed limit sqrt(vx^2 + vy^2) <= 0.2 + 2 n sqrt(sx^2 + sy^2).

Prints the number of flights and states checked, the largest excess outside a set, and
the flights' smallest speed-limit margin. Exit code 0 when every state is inside, 1
otherwise, 2 on a usage error. Needs numpy and onnx (bench/setup_venv.sh).

Usage: docking_containment.py MODEL_ONNX OUT/reach.json [--per-box K] [--seed S]
"""

import argparse
import itertools
import json
import sys

import numpy as np

N = 0.001027
M = 12.0
TOL = 1e-6


def load_net(path):
    import onnx
    from onnx import numpy_helper

    g = onnx.load(path).graph
    w = {i.name: numpy_helper.to_array(i).astype(np.float64) for i in g.initializer}
    ops = []
    for node in g.node:
        if node.op_type == "MatMul":
            ops.append(("mm", w[node.input[1]]))
        elif node.op_type == "Add":
            ops.append(("add", w[node.input[1]]))
        elif node.op_type == "Tanh":
            ops.append(("tanh", None))
        else:
            raise SystemExit(f"unexpected ONNX op {node.op_type}")

    def net(x):
        for op, p in ops:
            x = x @ p if op == "mm" else (x + p if op == "add" else np.tanh(x))
        return x

    try:
        import onnxruntime as ort

        sess = ort.InferenceSession(path)
        name = sess.get_inputs()[0].name
        rng = np.random.default_rng(0)
        for _ in range(20):
            p = np.array([[70, 70, -0.3, -0.3]]) + rng.random((1, 4)) * [36, 36, 0.6, 0.6]
            ref = sess.run(None, {name: p.astype(np.float32)})[0].astype(np.float64)
            assert np.abs(ref - net(p)).max() < 1e-5, "float64 network differs from onnxruntime"
    except ImportError:
        pass
    return net


def rhs(x, u):
    return np.stack(
        [
            x[:, 2],
            x[:, 3],
            3 * N * N * x[:, 0] + 2 * N * x[:, 3] + u[:, 0] / M,
            -2 * N * x[:, 2] + u[:, 1] / M,
        ],
        1,
    )


def rk4(x, u, h):
    """One classic RK4 step of length h of dynamics.m, the control u held."""
    k1 = rhs(x, u)
    k2 = rhs(x + h / 2 * k1, u)
    k3 = rhs(x + h / 2 * k2, u)
    k4 = rhs(x + h * k3, u)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("model")
    ap.add_argument("reach_json")
    ap.add_argument("--per-box", type=int, default=8)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    net = load_net(a.model)
    leaves = json.load(open(a.reach_json))["result"]["leaves"]
    rng = np.random.default_rng(a.seed)
    starts, owner = [], []
    for i, leaf in enumerate(leaves):
        b = np.array(leaf["init"])
        pts = [b[:, 0] + (b[:, 1] - b[:, 0]) * rng.random(4) for _ in range(a.per_box)]
        c = list(itertools.product(*b))
        pts += [np.array(c[k]) for k in rng.choice(len(c), 2, replace=False)]
        starts += pts
        owner += [i] * len(pts)
    x = np.array(starts)
    owner = np.array(owner)
    # Every leaf's sets as one array (leaf, instant, state, lo/hi); the instants after a
    # sub-box stopped are NaN and not checked.
    k_max = max(len(leaf["instants"]) for leaf in leaves)
    sets = np.full((len(leaves), k_max, 4, 2), np.nan)
    for i, leaf in enumerate(leaves):
        sets[i, : len(leaf["instants"])] = np.array(leaf["instants"])
    worst, checked, margin = -np.inf, 0, np.inf

    def check(x, k):
        nonlocal worst, checked
        if k >= k_max:
            return
        s = sets[owner, k]
        ok = ~np.isnan(s[:, 0, 0])
        ex = np.maximum(s[ok, :, 0] - x[ok], x[ok] - s[ok, :, 1])
        if ok.any():
            worst = max(worst, ex.max())
        checked += int(ok.sum())

    check(x, 0)
    h = 0.01
    for k in range(40):
        u = net(x)
        for _ in range(100):
            x = rk4(x, u, h)
            g = 0.2 + 2 * N * np.hypot(x[:, 0], x[:, 1]) - np.hypot(x[:, 2], x[:, 3])
            margin = min(margin, g.min())
        check(x, k + 1)
    print(f"{len(starts)} flights from {len(leaves)} sub-boxes, {checked} states checked")
    print(f"largest excess outside a set: {worst:.3e} (tolerance {TOL:g})")
    print(f"smallest speed-limit margin of the flights: {margin:.4f}")
    return 0 if worst <= TOL else 1


if __name__ == "__main__":
    sys.exit(main())

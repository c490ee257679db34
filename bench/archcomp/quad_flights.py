#!/usr/bin/env python3
"""Fly the competition's QUAD (ARCH-COMP AINNCS) independently of samara.

The plant is benchmarks/QUAD/dynamics.m transcribed term by term (typos included), the
controller the competition's ONNX file run by onnxruntime (float32, as published),
sample and hold at 0.1 s, classical RK4 with 100 steps per period, horizon 5 s. Initial
states: the 64 corners of x1..x6 in [-R, R] and N uniform random points (x7..x12 = 0).
Prints the range of x3 at t = 5 over all flights and how many leave the goal
[0.94, 1.06]: a falsification when one does, the margin when none does.

usage: bench/archcomp/quad_flights.py QUAD.onnx [--n 2000] [--radius 0.4] [--seed 0]
(numpy and onnxruntime: bench/setup_venv.sh)
"""
import argparse
import itertools

import numpy as np
import onnxruntime as ort

G, M, JX, JY, JZ, T = 9.81, 1.4, 0.054, 0.054, 0.104, 0.0


def dynamics_m(x, u):
    """dynamics.m, vectorised over rows of x (N x 12) and u (N x 3)."""
    s = lambda k: np.sin(x[:, k - 1])  # noqa: E731
    c = lambda k: np.cos(x[:, k - 1])  # noqa: E731
    X = lambda k: x[:, k - 1]  # noqa: E731
    t8 = np.tan(x[:, 7])
    return np.stack([
        c(8) * c(9) * X(4) + (s(7) * s(8) * c(9) - c(7) * s(9)) * X(5)
        + (c(7) * s(8) * c(9) + s(7) * s(9)) * X(6),
        c(8) * s(9) * X(4) + (s(7) * s(8) * s(9) - c(7) * c(9)) * X(5)
        + (c(7) * s(8) * s(9) + s(7) * c(9)) * X(6),
        s(8) * X(4) - s(7) * c(8) * X(5) - c(7) * c(8) * X(6),
        X(12) * X(5) * X(11) * X(6) - G * s(8),
        X(10) * X(6) - X(11) * X(6) - G * s(8),
        X(11) * X(4) - X(10) * X(5) + G * c(8) * c(7) - G - u[:, 0] / M,
        X(10) + s(7) * t8 * X(11) + c(7) * t8 * X(12),
        c(7) * X(11) - s(7) * X(12),
        s(7) * X(11) / c(8) - c(7) * X(12) / c(8),
        X(11) * X(12) * (JY - JZ) / JX + u[:, 1] / JX,
        (JZ - JX) * X(10) * X(12) / JY + u[:, 2] / JY,
        (JX - JY) * X(10) * X(11) / JZ + T / JZ,
    ], axis=1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("onnx")
    ap.add_argument("--n", type=int, default=2000)
    ap.add_argument("--radius", type=float, default=0.4)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    sess = ort.InferenceSession(a.onnx)
    name = sess.get_inputs()[0].name
    rng = np.random.default_rng(a.seed)
    r = a.radius
    corners = np.array(list(itertools.product([-r, r], repeat=6)))
    x = np.zeros((len(corners) + a.n, 12))
    x[: len(corners), :6] = corners
    x[len(corners):, :6] = rng.uniform(-r, r, (a.n, 6))
    h = 0.1 / 100
    for _ in range(50):
        # The published file takes a batch of one.
        xf = x.astype(np.float32)
        u = np.concatenate([sess.run(None, {name: xf[i:i + 1]})[0] for i in range(len(x))])
        u = u.astype(np.float64)
        for _ in range(100):
            k1 = dynamics_m(x, u)
            k2 = dynamics_m(x + h / 2 * k1, u)
            k3 = dynamics_m(x + h / 2 * k2, u)
            k4 = dynamics_m(x + h * k3, u)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    x3 = x[:, 2]
    out = np.sum((x3 < 0.94) | (x3 > 1.06) | ~np.isfinite(x3))
    print(f"QUAD (dynamics.m), x1..x6 in [-{r}, {r}]: {len(x3)} flights "
          f"({len(corners)} corners), x3 at t = 5 in [{np.nanmin(x3):.6f}, {np.nanmax(x3):.6f}]; "
          f"outside the goal [0.94, 1.06]: {out}")
    if out == 0:
        print(f"margin: {min(np.min(x3) - 0.94, 1.06 - np.max(x3)):.6f}")


if __name__ == "__main__":
    main()

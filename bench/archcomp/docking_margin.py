#!/usr/bin/env python3
"""Spacecraft docking: how much room the flights leave under the speed limit.

Flies N uniform starts of the initial set of examples/archcomp/spacecraft_docking.sys
(sx, sy in [70, 106], vx, vy in [-0.14, 0.14]) with benchmarks/Docking/dynamics.m
(numpy, classic RK4, 20 steps per 1 s period, control held) and the network in float64
from the ONNX weights (docking_containment.py's evaluator), and prints the distribution
over the starts of the margin 0.2 - max_t (|v| - 2 n |s|) over t in [0, 40]: the room a
sound enclosure has, everywhere in the initial set, before it crosses the limit.

Usage: docking_margin.py MODEL_ONNX [N]   (needs numpy and onnx: bench/setup_venv.sh)
Exit code 0; 2 on a usage error.
"""

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from docking_containment import N, load_net, rk4  # noqa: E402


def main() -> int:
    if len(sys.argv) not in (2, 3):
        print(__doc__.strip().splitlines()[-3], file=sys.stderr)
        return 2
    net = load_net(sys.argv[1])
    count = int(sys.argv[2]) if len(sys.argv) == 3 else 20000
    rng = np.random.default_rng(2)
    lo, hi = np.array([70, 70, -0.14, -0.14]), np.array([106, 106, 0.14, 0.14])
    x0 = lo + (hi - lo) * rng.random((count, 4))
    x = x0.copy()

    def g(x):
        return np.hypot(x[:, 2], x[:, 3]) - 2 * N * np.hypot(x[:, 0], x[:, 1])

    worst = g(x)
    h = 0.05
    for _ in range(40):
        u = net(x)
        for _ in range(20):
            x = rk4(x, u, h)
            worst = np.maximum(worst, g(x))
    margin = 0.2 - worst
    q = np.quantile(margin, [0, 0.01, 0.5, 0.99, 1])
    print(f"{count} starts; margin min {q[0]:.4f}, 1% {q[1]:.4f}, median {q[2]:.4f}, "
          f"99% {q[3]:.4f}, max {q[4]:.4f}")
    i = int(np.argmin(margin))
    print(f"tightest start: sx={x0[i, 0]:.3f} sy={x0[i, 1]:.3f} vx={x0[i, 2]:.4f} "
          f"vy={x0[i, 3]:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""CartPole (ARCH-COMP AINNCS 2024): why set-based reachability loses it, in numbers.

Linearises the closed loop's one-period map at the upright equilibrium, independently of
samara: the plant is benchmarks/CartPole/dynamics.m as `examples/archcomp/cartpole.sys`
states it (numpy, classic RK4 with 20 steps per 0.02 s period), the controller the
competition's model.onnx run by onnxruntime (float32, held over the period), and the
Jacobian taken by central differences (step 1e-4).

Prints the Jacobian, its eigenvalues (the flights' contraction per period), its
singular values and its rows' absolute sums (how much one period can widen a box or an
interval remainder, per state), and the network's gradient.

Usage: cartpole_period_map.py MODEL_ONNX     (needs numpy and onnxruntime:
bench/setup_venv.sh). Exit code 0; 2 on a usage error.
"""

import sys

import numpy as np


def main() -> int:
    if len(sys.argv) != 2:
        print("usage: cartpole_period_map.py MODEL_ONNX", file=sys.stderr)
        return 2
    import onnxruntime as ort

    sess = ort.InferenceSession(sys.argv[1])
    name = sess.get_inputs()[0].name

    def net(x):
        inp = np.asarray(x, dtype=np.float32).reshape(1, 4)
        return float(sess.run(None, {name: inp})[0].ravel()[0])

    def rhs(x, u):
        x1, x2, x3, x4 = x
        return np.array([
            x2,
            2 * u,
            x4,
            (0.08 * 0.41 * (9.8 * np.sin(x3) - 2 * u * np.cos(x3)) - 0.0021 * x4) / 0.0105,
        ])

    def period(x):
        u = net(x)
        h = 0.02 / 20
        for _ in range(20):
            k1 = rhs(x, u)
            k2 = rhs(x + h / 2 * k1, u)
            k3 = rhs(x + h / 2 * k2, u)
            k4 = rhs(x + h * k3, u)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return x

    x0, e, eye = np.zeros(4), 1e-4, np.eye(4)
    jac = np.column_stack([(period(x0 + e * eye[i]) - period(x0 - e * eye[i])) / (2 * e)
                           for i in range(4)])
    grad = [(net(x0 + e * eye[i]) - net(x0 - e * eye[i])) / (2 * e) for i in range(4)]
    np.set_printoptions(precision=4, suppress=True)
    print("one-period map's Jacobian at the equilibrium:\n", jac)
    print("eigenvalue magnitudes:", np.abs(np.linalg.eigvals(jac)))
    print("singular values:", np.linalg.svd(jac, compute_uv=False))
    print("row absolute sums (box widening per period):", np.abs(jac).sum(axis=1))
    print("network gradient d f / d x:", np.array(grad))
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""What the flights of the six-state initial set do (issue 14): the facts a set method
has to live with, measured on simulated flights, not on sets.

Flies the shipped reduced glider file (examples/archcomp/alsomitra_reduced.sys) from
the six-state initial set (+-0.01 on v_xp, v_yp, omega, theta; +-0.05 on x) with y
fixed at one height (default 2.0: the height only shifts x + y and never enters the
plant's right-hand side), the network's output clipped to [0.181, 0.193], with
`samara simulate --system`, and prints per instant:

  - the flights' spread in every state;
  - the range of the held control ex over the flights (is the network's output the
    same for every flight?);
  - the angle of attack alpha = atan(v_yp / v_xp) and the stall blend
    F = 1 / (1 + exp(2 (-alpha - alpha0) / delta)) of the plant (alpha0 = 14 deg,
    delta = 6 deg): where the flights cross the stall transition;
  - the least-squares affine fit of x + y on the six initial states: its R^2 and
    residual range (how far from affine the map from the initial set to x + y is).

Standard library only:

    python3 bench/reach/six_state_flights.py [--network adversarial_model_denorm.onnx]
        [--samples 1000] [--y 2.0] [--reference ../shared/reference] [--no-build]
"""

import argparse
import collections
import csv
import math
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
STATES = ["v_xp", "v_yp", "omega", "theta", "x", "y"]
ALPHA0 = 14 * math.pi / 180
DELTA = 6 * math.pi / 180


def system_file(y):
    """The shipped reduced file with the six-state set, y fixed, and the clip."""
    src = open(os.path.join(ROOT, "examples/archcomp/alsomitra_reduced.sys")).read()
    out = []
    for line in src.splitlines():
        if line.startswith("actuate ex = net[0]"):
            line = "actuate ex = net[0] clip [0.181, 0.193]"
        elif line.startswith("init "):
            continue
        out.append(line)
    out += [
        "init v_xp in [0.99, 1.01]",
        "init v_yp in [-0.01, 0.01]",
        "init omega in [-0.01, 0.01]",
        "init theta in [-0.01, 0.01]",
        "init x in [-0.05, 0.05]",
        f"init y in [{y!r}, {y!r}]",
    ]
    return "\n".join(out) + "\n"


def affine_fit(xs, ys):
    """Least squares y ~ c0 + c . x by the normal equations (Gauss-Jordan)."""
    n = len(xs[0]) + 1
    rows = [[1.0] + list(x) for x in xs]
    a = [[sum(r[i] * r[j] for r in rows) for j in range(n)] for i in range(n)]
    b = [sum(r[i] * y for r, y in zip(rows, ys)) for i in range(n)]
    m = [a[i] + [b[i]] for i in range(n)]
    for i in range(n):
        p = max(range(i, n), key=lambda r: abs(m[r][i]))
        m[i], m[p] = m[p], m[i]
        if m[i][i] == 0.0:
            continue
        for r in range(n):
            if r != i:
                f = m[r][i] / m[i][i]
                m[r] = [u - f * v for u, v in zip(m[r], m[i])]
    coef = [m[i][n] / m[i][i] if m[i][i] != 0.0 else 0.0 for i in range(n)]
    res = [y - sum(c * v for c, v in zip(coef, r)) for r, y in zip(rows, ys)]
    mean = sum(ys) / len(ys)
    tot = sum((y - mean) ** 2 for y in ys)
    r2 = 1.0 - sum(e * e for e in res) / tot if tot > 0 else 1.0
    return coef, r2, min(res), max(res)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--network", default="adversarial_model_denorm.onnx")
    ap.add_argument("--samples", type=int, default=1000)
    ap.add_argument("--y", type=float, default=2.0)
    ap.add_argument("--reference", default=os.path.join(ROOT, "..", "shared", "reference"))
    ap.add_argument("--no-build", action="store_true")
    args = ap.parse_args()
    exe = os.path.join(ROOT, "target", "release", "samara")
    if not args.no_build:
        subprocess.run(["cargo", "build", "--release", "-p", "samara-cli"], cwd=ROOT, check=True)
    net = os.path.join(args.reference, args.network)
    with tempfile.TemporaryDirectory() as tmp:
        sys_path = os.path.join(tmp, "six.sys")
        with open(sys_path, "w") as f:
            f.write(system_file(args.y))
        out = os.path.join(tmp, "sim")
        # Exit 1 only means some flight misses the file's goal (it has none here).
        r = subprocess.run(
            [exe, "simulate", "--system", sys_path, "--controller", net,
             "--samples", str(args.samples), "--no-plot", "--out", out],
            capture_output=True, text=True)
        if r.returncode not in (0, 1):
            sys.exit(f"samara simulate failed ({r.returncode}): {r.stderr.strip()}")
        by_t = collections.defaultdict(list)
        with open(os.path.join(out, "trajectories.csv")) as f:
            for row in csv.DictReader(f):
                by_t[round(float(row["t"]), 6)].append(row)
    starts = {r["start"]: [float(r[c]) for c in STATES] for r in by_t[0.0]}
    print(f"{args.network}, {len(starts)} flights from the six-state set, y0 = {args.y}")
    print(f"{'t':>5} " + " ".join(f"{c:>7}" for c in STATES)
          + "   ex range            alpha range        F range       x+y fit R^2 (residuals)")
    for t in sorted(by_t):
        if abs(t * 4 - round(t * 4)) > 1e-9 or (t > 2 and abs(t - round(t)) > 1e-9):
            continue
        rows = by_t[t]
        spread = [max(float(r[c]) for r in rows) - min(float(r[c]) for r in rows) for c in STATES]
        ex = [float(r["ex"]) for r in rows]
        al = [math.atan(float(r["v_yp"]) / float(r["v_xp"])) for r in rows]
        fb = [1.0 / (math.exp((-a - ALPHA0) * 2.0 / DELTA) + 1.0) for a in al]
        xs = [starts[r["start"]][:5] for r in rows]
        ys = [float(r["x"]) + float(r["y"]) for r in rows]
        fit = ""
        if t > 0:
            _, r2, lo, hi = affine_fit(xs, ys)
            fit = f"{r2:.4f} ({lo:+.3f}, {hi:+.3f})"
        print(f"{t:5.2f} " + " ".join(f"{s:7.4f}" for s in spread)
              + f"   [{min(ex):.5f}, {max(ex):.5f}]  [{min(al):+.3f}, {max(al):+.3f}]"
              + f"  [{min(fb):.3f}, {max(fb):.3f}]  {fit}")
    t_end = max(by_t)
    coef, r2, lo, hi = affine_fit([starts[r["start"]][:5] for r in by_t[t_end]],
                                  [float(r["x"]) + float(r["y"]) for r in by_t[t_end]])
    print(f"x + y at t = {t_end:g} ~ {coef[0]:.2f} + "
          + " + ".join(f"{c:.1f} {s}" for c, s in zip(coef[1:], STATES))
          + f"  (R^2 {r2:.4f}, residuals {lo:+.3f} .. {hi:+.3f})")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Spacecraft docking: what a box-hull check of the speed limit can prove.

JuliaReach's 2024 repeatability package (JuliaReach/ARCH2024_AINNCS_RE,
models/SpacecraftDocking/SpacecraftDocking.jl) calls docking verified after checking

    sqrt(vx^2 + vy^2) <= 0.2 + 2 n sqrt(sx^2 + sy^2)

on the interval hull of every reach set, with IntervalArithmetic.jl 0.20.9 (its
Manifest.toml). There `<=` between two intervals is IEEE 1788's weak `less`:
`a.lo <= b.lo && a.hi <= b.hi` (the definition is commented "Weakly less" in
IntervalArithmetic.jl before 1.0; see its issue #512), not
"every point of a is below every point of b" (`a.hi <= b.lo`), which a proof needs.

This script takes simulated flights (samara simulate --system
examples/archcomp/spacecraft_docking.sys --controller model.onnx: states of real
trajectories, so their hull at an instant is inside every sound enclosure of that
instant) and evaluates both comparisons on that hull at each whole second. Where the
sound comparison fails on the flights' own hull, no sound enclosure's hull can pass it,
while the weak comparison can pass on any larger hull whose ends line up.

Usage: docking_box_check.py TRAJECTORIES_CSV
Prints one line per instant: t, the hull's |v| and 0.2 + 2 n |s| intervals, the weak and
the sound verdict, and the largest speed-limit value over the flights themselves.
Exit code 0; 2 on a usage error.
"""

import csv
import math
import sys

N = 0.001027


def main() -> int:
    if len(sys.argv) != 2:
        print("usage: docking_box_check.py TRAJECTORIES_CSV", file=sys.stderr)
        return 2
    hull = {}
    worst = {}
    with open(sys.argv[1], newline="") as f:
        for row in csv.DictReader(f):
            t = float(row["t"])
            if abs(t - round(t)) > 1e-9:
                continue
            t = round(t)
            v = [float(row[k]) for k in ("sx", "sy", "vx", "vy")]
            h = hull.setdefault(t, [[math.inf, -math.inf] for _ in range(4)])
            for b, x in zip(h, v):
                b[0] = min(b[0], x)
                b[1] = max(b[1], x)
            g = math.hypot(v[2], v[3]) - 2 * N * math.hypot(v[0], v[1])
            worst[t] = max(worst.get(t, -math.inf), g)

    def abs_range(b):
        lo, hi = b
        if lo <= 0 <= hi:
            return 0.0, max(-lo, hi)
        return min(abs(lo), abs(hi)), max(abs(lo), abs(hi))

    print("t  |v| in           0.2+2n|s| in      weak<=  sound<=  max over flights of |v|-2n|s|")
    for t in sorted(hull):
        sx, sy, vx, vy = hull[t]
        ax, ay = abs_range(vx), abs_range(vy)
        px, py = abs_range(sx), abs_range(sy)
        speed = (math.hypot(ax[0], ay[0]), math.hypot(ax[1], ay[1]))
        limit = (0.2 + 2 * N * math.hypot(px[0], py[0]), 0.2 + 2 * N * math.hypot(px[1], py[1]))
        weak = speed[0] <= limit[0] and speed[1] <= limit[1]
        sound = speed[1] <= limit[0]
        print(
            f"{t:<3}[{speed[0]:.3f}, {speed[1]:.3f}]  [{limit[0]:.3f}, {limit[1]:.3f}]  "
            f"{'pass' if weak else 'fail':<7} {'pass' if sound else 'fail':<8} {worst[t]:.3f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())

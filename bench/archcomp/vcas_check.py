#!/usr/bin/env python3
"""Independent transcription of ARCH-COMP 2024 VCAS (planeDynamics.m, Specifications.txt)
in plain Python: reads the nine .nnet files itself (clip to the header's min/max,
normalise by the header's means/ranges, ReLU layers, linear last layer) and flies the
closed loop with one acceleration strategy. No samara code is used.

    python3 bench/archcomp/vcas_check.py DIR [middle|min|max] [200|5000] [N]

prints, per initial climb rate, how many of N evenly spaced h(0) in [-133, -129] stay
safe (|h| > 100 at steps 0..10) and the first violating start with its trajectory.
With `point H HDOT` it prints one step's scores, argmax and next state instead.
"""
import sys

ADV = ["COC", "DNC", "DND", "DES1500", "CL1500", "SDES1500", "SCL1500", "SDES2500", "SCL2500"]
G = 32.2
ACC = [
    [-G / 8, 0.0, G / 8],
    [-G / 3, -7 * G / 24, -G / 4],
    [G / 4, 7 * G / 24, G / 3],
    [-G / 3, -7 * G / 24, -G / 4],
    [G / 4, 7 * G / 24, G / 3],
    [-G / 3],
    [G / 3],
    [-G / 3],
    [G / 3],
]


def read_nnet(path):
    lines = [l for l in open(path) if not l.startswith("//") and l.strip()]
    nums = lambda l: [float(v) for v in l.strip().rstrip(",").split(",")]
    nl, n_in, n_out, _ = [int(v) for v in nums(lines[0])]
    sizes = [int(v) for v in nums(lines[1])]
    mins, maxs, means, ranges = nums(lines[3]), nums(lines[4]), nums(lines[5]), nums(lines[6])
    layers, i = [], 7
    for k in range(nl):
        w = [nums(lines[i + r]) for r in range(sizes[k + 1])]
        i += sizes[k + 1]
        b = [nums(lines[i + r])[0] for r in range(sizes[k + 1])]
        i += sizes[k + 1]
        layers.append((w, b))
    return mins, maxs, means, ranges, layers


def evaluate(net, x):
    mins, maxs, means, ranges, layers = net
    a = [(min(max(v, mins[i]), maxs[i]) - means[i]) / ranges[i] for i, v in enumerate(x)]
    for k, (w, b) in enumerate(layers):
        z = [sum(wi * ai for wi, ai in zip(row, a)) + bi for row, bi in zip(w, b)]
        a = z if k == len(layers) - 1 else [max(v, 0.0) for v in z]
    return [v * ranges[-1] + means[-1] for v in a]


def argmax(v):
    k = 0
    for i, x in enumerate(v):
        if x > v[k]:
            k = i
    return k


def pick(row, strategy):
    if strategy == "middle":
        return row[(len(row) - 1) // 2]
    return min(row) if strategy == "min" else max(row)


def step(nets, h, hd, tau, adv, strategy, norm):
    scores = evaluate(nets[adv], [h, hd * 200.0 / norm, tau])
    new = argmax(scores)
    acc = pick(ACC[new], strategy)
    return (h - hd - 0.5 * acc, hd + acc, tau - 1, new), scores, acc


def fly(nets, h, hd, strategy, norm):
    traj = [(h, hd, 25.0, 0)]
    for _ in range(10):
        s, _, _ = step(nets, *traj[-1], strategy, norm)
        traj.append(s)
    return traj


def main():
    d = sys.argv[1]
    nets = [read_nnet(f"{d}/VertCAS_noResp_pra0{i}_v9_20HU_200.nnet") for i in range(1, 10)]
    if len(sys.argv) > 2 and sys.argv[2] == "point":
        h, hd = float(sys.argv[3]), float(sys.argv[4])
        norm = float(sys.argv[5]) if len(sys.argv) > 5 else 200.0
        for strategy in ["middle"]:
            s, scores, acc = step(nets, h, hd, 25.0, 0, strategy, norm)
            print("scores", [repr(v) for v in scores])
            print("argmax", s[3], ADV[s[3]], "acc", repr(acc), "next", [repr(v) for v in s])
        return
    strategy = sys.argv[2] if len(sys.argv) > 2 else "middle"
    norm = float(sys.argv[3]) if len(sys.argv) > 3 else 200.0
    n = int(sys.argv[4]) if len(sys.argv) > 4 else 401
    for hd in [-19.5, -22.5, -25.5, -28.5]:
        bad = None
        safe = 0
        for j in range(n):
            h0 = -133.0 + 4.0 * j / (n - 1)
            t = fly(nets, h0, hd, strategy, norm)
            if all(abs(x[0]) > 100 for x in t):
                safe += 1
            elif bad is None:
                bad = (h0, t)
        print(f"hdot0 {hd}: {safe}/{n} safe ({strategy}, hdot range {norm:g})")
        if bad:
            k = next(i for i, x in enumerate(bad[1]) if abs(x[0]) <= 100)
            print(f"  first violation from h0 = {bad[0]!r} at step {k}: "
                  + " ".join(f"({x[0]:.3f},{x[1]:.3f},{ADV[x[3]]})" for x in bad[1][: k + 1]))


if __name__ == "__main__":
    main()

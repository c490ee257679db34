#!/usr/bin/env python3
"""Compare two samara binaries on VNN-COMP instances under the same machine load.

Each instance is run by both binaries in turn (`samara verify-vnnlib --json`, a process
per instance), so a loaded machine slows both alike; prints the instances where either
took over 3 s and the sums of wall and child CPU time per binary. Verdicts are printed
beside the times so a change of verdict shows.

Usage: bench/vnncomp/ab_acasxu.py BENCHMARK_DIR LIST BIN_A BIN_B [--timeout S]
LIST: lines `network.onnx,property.vnnlib` relative to BENCHMARK_DIR (e.g. cut -d, -f1,2
of acasxu_instances.csv, filtered).
"""

import argparse
import json
import resource
import subprocess
import time


def cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("bench")
    ap.add_argument("list")
    ap.add_argument("bin_a")
    ap.add_argument("bin_b")
    ap.add_argument("--timeout", default="200")
    a = ap.parse_args()
    bins = {"A": a.bin_a, "B": a.bin_b}
    pairs = [l.strip().split(",") for l in open(a.list) if l.strip()]
    tot = {k: [0.0, 0.0] for k in bins}
    for onnx, prop in pairs:
        row = {}
        for k, b in bins.items():
            c0, t0 = cpu(), time.time()
            r = subprocess.run([b, "verify-vnnlib", "--network", f"{a.bench}/{onnx}",
                                "--property", f"{a.bench}/{prop}", "--json",
                                "--timeout", a.timeout],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
            w, c = time.time() - t0, cpu() - c0
            tot[k][0] += w
            tot[k][1] += c
            row[k] = (json.loads(r.stdout)["result"], round(w, 2), round(c, 2))
        if max(v[1] for v in row.values()) > 3:
            print(onnx, prop, row)
    for k, (w, c) in tot.items():
        print(f"{k} {bins[k]}: wall {w:.1f} s, cpu {c:.1f} s")


if __name__ == "__main__":
    main()

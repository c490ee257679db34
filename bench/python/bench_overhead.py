#!/usr/bin/env python3
"""Overhead of the Python API against the CLI on the same work.

For each workload: the median wall time of the Python call (in-process, after the
network and spec are loaded once) and of the CLI (a fresh `samara` process, which also
loads its files and, for simulate and reach, writes its output files), their ratio, and
the computation time each reports itself (`seconds` in the JSON) where there is one.

    python bench/python/bench_overhead.py [--cli target/release/samara] [--reps 5] [--json out.json]

Run from the repository root with the `samara` wheel installed (docs/python.md).
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import samara

ROOT = Path(__file__).resolve().parents[2]
REF = Path(os.environ.get("SAMARA_REFERENCE", ROOT.parent / "shared" / "reference"))
SPEC = ROOT / "models" / "alsomitra" / "alsomitra.spec"


def median_time(f, reps):
    """Median wall time and the outputs of every repetition."""
    ts, outs = [], []
    for _ in range(reps):
        t0 = time.perf_counter()
        outs.append(f())
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), outs


def median_comp(comp, outs):
    if comp is None or not all(isinstance(o, dict) for o in outs):
        return None
    return statistics.median(comp(o) for o in outs)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cli", default=str(ROOT / "target" / "release" / "samara"))
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--json", help="write the rows as JSON here")
    a = ap.parse_args()
    if not os.access(a.cli, os.X_OK):
        sys.exit(f"{a.cli}: no samara binary; build it with cargo build --release -p samara-cli")

    norm = samara.Network.from_onnx(REF / "base_model_norm.onnx")
    denorm = samara.Network.from_onnx(REF / "base_model_denorm.onnx")
    spec = samara.Spec(SPEC)
    data = samara.read_table(REF / "Training_Data_Normalised.csv")[:100]
    tmp = Path(tempfile.mkdtemp(prefix="samara-bench-"))
    np_csv = tmp / "data100.csv"
    import numpy as np

    np.savetxt(np_csv, data, delimiter=",", fmt="%.17g")

    def run_cli(args):
        r = subprocess.run([a.cli, *args], capture_output=True, text=True, cwd=ROOT)
        if r.returncode not in (0, 1):
            sys.exit(f"samara {' '.join(args)} failed: {r.stderr}")
        return json.loads(r.stdout)

    work = [
        (
            "critical p1 (base_model_norm)",
            lambda: spec.critical(property="p1", param="ystar", networks={"f": norm}).as_dict(),
            ["critical", str(SPEC), "--property", "p1", "--param", "ystar",
             "--network", f"f={REF / 'base_model_norm.onnx'}", "--json"],
            lambda d: d["seconds"],
        ),
        (
            "verify p1-p4 (ystar=2)",
            lambda: [r.as_dict() for p in ["p1", "p2", "p3", "p4"]
                     for r in spec.verify(networks={"f": norm}, params={"ystar": 2}, property=p)],
            None,  # several properties: the CLI runs them in one call below
            None,
        ),
        (
            "robustness P5 table, 100 points",
            lambda: samara.robustness(norm, data, eps=[1e-3, 1e-2], lipschitz=[1e-2, 1e-1]).as_dict(),
            ["robustness", "--network", str(REF / "base_model_norm.onnx"), "--data", str(np_csv),
             "--eps", "1e-3,1e-2", "--lipschitz", "1e-2,1e-1", "--json"],
            lambda d: d["seconds"],
        ),
        (
            "simulate 9 published starts (network)",
            lambda: samara.simulate(controller=denorm),
            ["simulate", "--controller", str(REF / "base_model_denorm.onnx"), "--out", str(tmp / "sim"),
             "--no-plot", "--json"],
            lambda d: d["wall_seconds"],
        ),
        (
            "reach y0 in [2, 2.1], horizon 2",
            lambda: samara.reach(denorm, y0=(2.0, 2.1), horizon=2.0, goal_ystar=5.0).as_dict(),
            ["reach", "--network", str(REF / "base_model_denorm.onnx"), "--y0", "2:2.1", "--horizon", "2",
             "--goal-ystar", "5", "--out", str(tmp / "reach"), "--json"],
            lambda d: d["seconds"],
        ),
    ]
    verify_cli = ["verify", str(SPEC), "--param", "ystar=2", "--network",
                  f"f={REF / 'base_model_norm.onnx'}", "--json"]
    rows = []
    print(f"{'workload':<40} {'python s':>10} {'CLI s':>10} {'ratio':>7} {'py comp s':>10} {'cli comp s':>10}")
    for name, py, cli, comp in work:
        tp, out_p = median_time(py, a.reps)
        if cli is None:
            # one CLI call per property, as the Python loop does
            tc_parts = []
            for p in ["p1", "p2", "p3", "p4"]:
                args = ["verify", str(SPEC), "--property", p] + verify_cli[2:]
                t, _ = median_time(lambda: run_cli(args), a.reps)
                tc_parts.append(t)
            tc, out_c = sum(tc_parts), None
            cp = cc = None
        else:
            tc, out_c = median_time(lambda: run_cli(cli), a.reps)
            cp = median_comp(comp, out_p)
            cc = median_comp(comp, out_c)
        row = {"workload": name, "python_s": tp, "cli_s": tc, "ratio_python_over_cli": tp / tc,
               "python_compute_s": cp, "cli_compute_s": cc}
        rows.append(row)
        f = lambda v: f"{v:10.4f}" if isinstance(v, float) else f"{'-':>10}"
        print(f"{name:<40} {tp:10.4f} {tc:10.4f} {tp / tc:7.3f} {f(cp)} {f(cc)}")
    shutil.rmtree(tmp, ignore_errors=True)
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""samara on the VNN-COMP 2021 ACAS Xu benchmark, beside the competition's tools.

Runs `samara vnncomp` on every instance of `acasxu_instances.csv` (186), then prints per
instance samara's verdict and time beside nnenum, Marabou and VeriNet (and a-b-CROWN when
its CSV is there), the disagreements (a decided verdict against a decided verdict), the
totals, a per-property breakdown, the instances samara leaves undecided, and, when
onnxruntime is importable, re-checks every `sat` counterexample: the inputs are run
through the ONNX file by onnxruntime and the whole VNN-LIB property is evaluated at them.

Python 3 standard library only (onnxruntime and numpy optional: bench/setup_venv.sh, or
`python3 -m venv V && V/bin/pip install onnxruntime numpy`).

Usage:
  bench/vnncomp/bench_acasxu.py BENCHMARK_DIR RESULTS_DIR [--samara BIN]
      [--timeout-scale F] [--out DIR] [--reuse SAMARA_RESULTS.csv] [--per-process]
BENCHMARK_DIR: `benchmarks/acasxu` of stanleybak/vnncomp2021 (env SAMARA_ACASXU_DIR);
RESULTS_DIR: `results_csv` of stanleybak/vnncomp2021_results (env SAMARA_VNNCOMP_RESULTS).
See bench/vnncomp/README.md for how to get them.
"""

import argparse
import csv
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PEERS = ["nnenum", "Marabou", "VeriNet", "a-b-CROWN"]
NNENUM_TOTAL_2021 = 285  # seconds, nnenum's ACAS Xu total in the VNN-COMP 2021 report


def norm(word):
    w = (word or "").strip().lower()
    if w in ("holds", "unsat"):
        return "unsat"
    if w in ("violated", "sat"):
        return "sat"
    if w in ("timeout", "unknown"):
        return w
    return "error" if w else "-"


def key(onnx, vnnlib):
    return (os.path.basename(onnx), os.path.basename(vnnlib))


def read_peers(results_dir):
    peers = {}
    for p in PEERS:
        f = Path(results_dir) / f"{p}.csv"
        if not f.exists():
            continue
        rows = {}
        with open(f, newline="") as fh:
            for r in csv.reader(fh):
                if len(r) >= 6 and r[0] == "acasxu":
                    try:
                        t = float(r[5])
                    except ValueError:
                        t = float("nan")
                    rows[key(r[1], r[2])] = (norm(r[4]), t)
        peers[p] = rows
    return peers


# --- a small VNN-LIB evaluator (for the onnxruntime re-check) -------------------------

def sexprs(text):
    text = re.sub(r";[^\n]*", "", text)
    toks = re.findall(r"\(|\)|[^\s()]+", text)
    stack = [[]]
    for t in toks:
        if t == "(":
            stack.append([])
        elif t == ")":
            e = stack.pop()
            stack[-1].append(e)
        else:
            stack[-1].append(t)
    return stack[0]


def ev(e, env):
    if isinstance(e, str):
        return env[e] if e in env else float(e)
    op, args = e[0], e[1:]
    if op == "and":
        return all(ev(a, env) for a in args)
    if op == "or":
        return any(ev(a, env) for a in args)
    vals = [ev(a, env) for a in args]
    if op == "+":
        return sum(vals)
    if op == "-":
        return -vals[0] if len(vals) == 1 else vals[0] - sum(vals[1:])
    if op == "*":
        r = 1.0
        for v in vals:
            r *= v
        return r
    cmp = {"<=": lambda a, b: a <= b, ">=": lambda a, b: a >= b,
           "<": lambda a, b: a < b, ">": lambda a, b: a > b, "=": lambda a, b: a == b}
    return all(cmp[op](a, b) for a, b in zip(vals, vals[1:]))


def property_holds_at(vnnlib_text, env):
    return all(ev(e[1], env) for e in sexprs(vnnlib_text) if e and e[0] == "assert")


def confirm_with_onnxruntime(onnx_path, vnnlib_path, x):
    import numpy as np
    import onnxruntime as ort

    s = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
    inp = s.get_inputs()[0]
    shape = [d if isinstance(d, int) else 1 for d in inp.shape]
    # The network's own input type: float32, or float64 (nn4sys's networks).
    dtype = np.float64 if inp.type == "tensor(double)" else np.float32
    y = s.run(None, {inp.name: np.array(x, dtype=dtype).reshape(shape)})[0].ravel()
    env = {f"X_{i}": float(v) for i, v in enumerate(x)}
    env.update({f"Y_{j}": float(v) for j, v in enumerate(y)})
    return property_holds_at(Path(vnnlib_path).read_text(), env), [float(v) for v in y]


# --------------------------------------------------------------------------------------

def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("benchmark", nargs="?", default=os.environ.get("SAMARA_ACASXU_DIR"))
    ap.add_argument("results", nargs="?", default=os.environ.get("SAMARA_VNNCOMP_RESULTS"))
    ap.add_argument("--samara", default=None, help="samara binary (default: build release)")
    ap.add_argument("--timeout-scale", default="1")
    ap.add_argument("--out", default=None, help="folder for samara's results (default: a temp folder)")
    ap.add_argument("--reuse", default=None, help="read samara's results CSV and JSON from an earlier run instead of running")
    ap.add_argument("--per-process", action="store_true",
                    help="run `samara verify-vnnlib` once per instance and count each process's "
                         "whole wall time (launch, ONNX load, VNN-LIB parse included), the "
                         "competition's way, instead of one `samara vnncomp` process")
    a = ap.parse_args()
    if not a.benchmark or not a.results:
        ap.error("give BENCHMARK_DIR and RESULTS_DIR (or set SAMARA_ACASXU_DIR and SAMARA_VNNCOMP_RESULTS); see bench/vnncomp/README.md")
    bench = Path(a.benchmark)
    inst = bench / "acasxu_instances.csv"
    if not inst.exists():
        sys.exit(f"{inst}: not found (BENCHMARK_DIR is benchmarks/acasxu of stanleybak/vnncomp2021)")
    peers = read_peers(a.results)
    if not peers:
        sys.exit(f"{a.results}: no nnenum.csv/Marabou.csv/VeriNet.csv (RESULTS_DIR is results_csv of stanleybak/vnncomp2021_results)")

    if a.reuse:
        out_csv = Path(a.reuse)
        js = json.loads(out_csv.with_suffix(".json").read_text())
        wall = js.get("wall_seconds", js["total_seconds"])
    else:
        binary = a.samara
        if binary is None:
            subprocess.run(["cargo", "build", "--release", "-q", "-p", "samara-cli"], cwd=REPO, check=True)
            binary = str(REPO / "target/release/samara")
        out = Path(a.out) if a.out else Path(os.environ.get("TMPDIR", "/tmp")) / f"samara_acasxu_{os.getpid()}"
        out.mkdir(parents=True, exist_ok=True)
        out_csv = out / "samara_acasxu.csv"
        t0 = time.time()
        if a.per_process:
            js = run_per_process(binary, bench, inst, float(a.timeout_scale))
            js["wall_seconds"] = time.time() - t0
            out_csv.with_suffix(".json").write_text(json.dumps(js))
            ours = {key(r["onnx"], r["vnnlib"]): r for r in js["instances"]}
            return report(a, bench, peers, js, ours, js["wall_seconds"])
        p = subprocess.run([binary, "vnncomp", str(inst), "--out", str(out_csv),
                            "--timeout-scale", a.timeout_scale, "--json"],
                           stdout=subprocess.PIPE, check=True)
        wall = time.time() - t0
        js = json.loads(p.stdout)
        js["wall_seconds"] = wall
        out_csv.with_suffix(".json").write_text(json.dumps(js))
    ours = {key(r["onnx"], r["vnnlib"]): r for r in js["instances"]}
    return report(a, bench, peers, js, ours, wall)


def run_per_process(binary, bench, inst, scale):
    """Every instance in its own `samara verify-vnnlib --json` process; an instance's time
    is the process's whole wall time, start-up included. Returns the shape of
    `samara vnncomp --json`'s document (instances, counts)."""
    rows, counts = [], {}
    with open(inst, newline="") as fh:
        lines = [r for r in csv.reader(fh) if len(r) >= 3]
    for onnx, vnnlib, timeout in ((r[0].strip(), r[1].strip(), float(r[2])) for r in lines):
        t0 = time.time()
        p = subprocess.run([binary, "verify-vnnlib", "--network", str(bench / onnx),
                            "--property", str(bench / vnnlib),
                            "--timeout", str(timeout * scale), "--json"],
                           stdout=subprocess.PIPE)
        secs = time.time() - t0
        if p.returncode not in (0, 1):
            sys.exit(f"{onnx} {vnnlib}: samara exited {p.returncode}")
        d = json.loads(p.stdout)
        word = d["result"]
        if word == "unknown" and "timeout" in json.dumps(d.get("unknown_reason")).lower():
            word = "timeout"
        counts[word] = counts.get(word, 0) + 1
        rows.append({"onnx": onnx, "vnnlib": vnnlib, "result": word, "seconds": secs,
                     "counterexample": d.get("counterexample")})
        print(f"{os.path.basename(onnx)} {vnnlib} {word} {secs:.2f}", file=sys.stderr, flush=True)
    return {"instances": rows, "counts": counts}


def report(a, bench, peers, js, ours, wall):
    names = [p for p in PEERS if p in peers]
    print(f"{'instance':<34} {'samara':>16} " + " ".join(f"{p:>18}" for p in names))
    disagreements, undecided = [], []
    per_prop = {}
    for k, r in ours.items():
        row = f"{k[0].replace('ACASXU_run2a_', '').replace('_batch_2000.onnx', ''):>5} {k[1]:<28}"
        row += f" {r['result']:>8} {r['seconds']:7.2f}"
        for p in names:
            v, t = peers[p].get(k, ("-", float("nan")))
            row += f" {v:>9} {t:8.2f}"
            if r["result"] in ("sat", "unsat") and v in ("sat", "unsat") and v != r["result"]:
                disagreements.append((k, p, r["result"], v))
        print(row)
        if r["result"] not in ("sat", "unsat"):
            undecided.append((k, r["result"]))
        pp = per_prop.setdefault(k[1], {"n": 0, "unsat": 0, "sat": 0, "other": 0, "s": 0.0, "nnenum": 0.0})
        pp["n"] += 1
        pp[r["result"] if r["result"] in ("sat", "unsat") else "other"] += 1
        pp["s"] += r["seconds"]
        t = peers.get("nnenum", {}).get(k, ("-", 0.0))[1]
        pp["nnenum"] += t if t == t else 0.0

    print("\nper property:  n  unsat  sat  undecided  samara s  nnenum s")
    for prop in sorted(per_prop, key=lambda s: int(re.sub(r"\D", "", s) or 0)):
        pp = per_prop[prop]
        print(f"  {prop:<12} {pp['n']:3} {pp['unsat']:6} {pp['sat']:4} {pp['other']:10} {pp['s']:9.1f} {pp['nnenum']:9.1f}")

    decided = sum(1 for r in ours.values() if r["result"] in ("sat", "unsat"))
    total = sum(r["seconds"] for r in ours.values())
    print(f"\nsamara: {decided}/{len(ours)} decided; counts {js['counts']}; "
          f"sum of instance times {total:.1f} s, wall {wall:.1f} s "
          f"(this machine, {os.cpu_count()} cores)")
    dec_total = sum(r["seconds"] for r in ours.values() if r["result"] in ("sat", "unsat"))
    print(f"samara over its decided instances: {dec_total:.1f} s")
    for p in names:
        mine = [peers[p].get(k, ("-", float("nan"))) for k in ours]  # the 186 instances only
        tot = sum(t for v, t in mine if v in ("sat", "unsat") and t == t)
        dec = sum(1 for v, _ in mine if v in ("sat", "unsat"))
        print(f"{p}: {dec}/{len(mine)} decided, {tot:.1f} s over its decided instances "
              f"(VNN-COMP 2021 hardware, AWS instances per tool, not this machine)")
    print(f"(nnenum's published ACAS Xu total: about {NNENUM_TOTAL_2021} s)")
    print(f"\ndisagreements with a decided peer: {len(disagreements)}")
    for d in disagreements:
        print(f"  {d[0]}: samara {d[2]}, {d[1]} {d[3]}")
    print(f"undecided by samara: {len(undecided)}")
    for k, w in undecided:
        print(f"  {k[0]} {k[1]}: {w}")

    sats = [(k, r) for k, r in ours.items() if r["result"] == "sat"]
    try:
        import onnxruntime  # noqa: F401
        have_ort = True
    except ImportError:
        have_ort = False
    if not have_ort:
        print(f"\n{len(sats)} sat counterexamples: not re-checked (onnxruntime is not installed; bench/setup_venv.sh)")
    else:
        ok = 0
        for k, r in sats:
            x = r["counterexample"]["inputs"]
            good, y = confirm_with_onnxruntime(bench / k[0], bench / k[1], x)
            ok += good
            if not good:
                print(f"  NOT CONFIRMED by onnxruntime: {k}: x={x} y={y}")
        print(f"\nsat counterexamples confirmed by onnxruntime (float32 outputs, whole property): {ok}/{len(sats)}")
        if ok != len(sats):
            return 1
    return 1 if disagreements else 0


if __name__ == "__main__":
    sys.exit(main())

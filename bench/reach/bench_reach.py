#!/usr/bin/env python3
"""Closed-loop reachability benchmark: `samara reach` on the published setting.

Runs the release binary on both published raw-unit networks
(../shared/reference/base_model_denorm.onnx, adversarial_model_denorm.onnx):

  1. published: reduced model, y0 in [1.4286, 4.2857], horizon 20, period 0.5,
     goal |x + y| <= 2 at t = 20 (the CORA setting of the paper);
  2. full:      the same on the full (four-quadrant, 7-state) model (full-taylor: on
                 Taylor-model sets);
  3. six-state: the reduced model from an initial set uncertain in all six states
     (+-0.01 on v_xp, v_yp, omega, theta; +-0.05 on x; y as published).

Per run it prints wall seconds, verdict, the width of the x + y enclosure at t = 20,
the sampled width, their ratio, the number of sub-boxes, and the speed-up over CORA's
published time ("over 8 hours in some cases" for the reduced model with 8-16 manual
splits): 8 h / samara's wall time. Each run has a timeout (default 600 s); a run that
times out or fails is reported as such and the benchmark goes on.

Standard library only:

    python3 bench/reach/bench_reach.py [--threads 2] [--timeout 600] [--out DIR]
        [--only published,full,six-state] [--reference ../shared/reference] [--no-build]

Writes DIR/results.json (and each run's reach.json/png/svg under DIR/<run>/).
"""

import argparse
import json
import os
import signal
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CORA_SECONDS = 8 * 3600.0  # "over 8 hours in some cases" (reduced model, 8-16 splits)
NETWORKS = ["base_model_denorm.onnx", "adversarial_model_denorm.onnx"]
Y0 = "1.4285714285714286:4.285714285714286"  # 0.1/0.07 : 0.3/0.07
COMMON = ["--y0", Y0, "--period", "0.5", "--goal-ystar", "2"]
RUNS = {
    "published": ["--model", "reduced"],
    "full": ["--model", "full"],
    # The full model on Taylor-model sets (polynomial stand-ins for omega |omega|;
    # the built-in glider's Taylor default: order 2, symbolic:7).
    "full-taylor": ["--model", "full", "--sets", "taylor"],
    "six-state": [
        "--model", "reduced",
        "--init", "v_xp=0.99:1.01",
        "--init", "v_yp=-0.01:0.01",
        "--init", "omega=-0.01:0.01",
        "--init", "theta=-0.01:0.01",
        "--init", "x=-0.05:0.05",
    ],
}


def build(binary):
    print("building the release binary ...", flush=True)
    r = subprocess.run(["cargo", "build", "--release", "-p", "samara-cli"], cwd=ROOT)
    if r.returncode != 0 or not os.path.exists(binary):
        sys.exit("cargo build --release -p samara-cli failed")


def run_one(binary, net, args, out_dir, threads, timeout, horizon):
    cmd = [binary, "reach", "--network", net, *COMMON, "--horizon", str(horizon), *args,
           "--threads", str(threads), "--out", out_dir, "--json"]
    t0 = time.monotonic()
    # Own process group, so a timeout stops the run and nothing else.
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, start_new_session=True)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        return {"status": "timeout", "wall": time.monotonic() - t0, "cmd": cmd}
    wall = time.monotonic() - t0
    rec = {"status": "ok", "wall": wall, "exit": p.returncode, "cmd": cmd}
    if p.returncode not in (0, 1):
        rec["status"] = "error"
        rec["stderr"] = err.strip()[-2000:]
        return rec
    try:
        rec["summary"] = json.loads(out)
    except json.JSONDecodeError:
        rec["status"] = "error"
        rec["stderr"] = (out + err).strip()[-2000:]
    return rec


def fmt(v, width, spec):
    return format("-" if v is None else format(v, spec), f">{width}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reference", default=os.path.join(ROOT, "..", "shared", "reference"))
    ap.add_argument("--binary", default=os.path.join(ROOT, "target", "release", "samara"))
    ap.add_argument("--threads", type=int, default=2, help="worker threads (the issue's target: 2 cores)")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per run")
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "bench-reach"))
    ap.add_argument("--only", default=",".join(RUNS), help="comma-separated subset of " + ",".join(RUNS))
    ap.add_argument("--horizon", type=float, default=20.0,
                    help="horizon (20 as published; smaller only for a smoke test)")
    ap.add_argument("--no-build", action="store_true", help="use the existing binary as is")
    a = ap.parse_args()

    runs = [r.strip() for r in a.only.split(",") if r.strip()]
    unknown = [r for r in runs if r not in RUNS]
    if unknown:
        sys.exit(f"--only: unknown run(s) {unknown}; choose from {list(RUNS)}")
    if not a.no_build:
        build(a.binary)
    elif not os.path.exists(a.binary):
        sys.exit(f"{a.binary} not found; build it with cargo build --release -p samara-cli")
    nets = [os.path.join(a.reference, n) for n in NETWORKS]
    missing = [n for n in nets if not os.path.exists(n)]
    if missing:
        sys.exit(f"missing published networks: {missing} (give --reference DIR)")
    os.makedirs(a.out, exist_ok=True)

    print(f"samara reach, {a.threads} thread(s), timeout {a.timeout:.0f} s per run; "
          f"goal |x + y| <= 2 at t = {a.horizon:g}; CORA: over 8 h (reduced model, 8-16 manual splits)")
    head = (f"{'run':<12} {'network':<30} {'wall s':>8} {'verdict':<9} {'x+y width':>10} "
            f"{'sampled':>10} {'ratio':>7} {'boxes':>6} {'8 h / wall':>11}")
    print(head)
    print("-" * len(head))
    results = []
    for run in runs:
        for net in nets:
            name = os.path.basename(net)
            out_dir = os.path.join(a.out, f"{run}-{name.replace('.onnx', '')}")
            rec = run_one(a.binary, net, RUNS[run], out_dir, a.threads, a.timeout, a.horizon)
            rec.update({"run": run, "network": name})
            results.append(rec)
            s = rec.get("summary", {})
            if rec["status"] == "ok":
                verdict = s.get("verdict")
                # Taylor-model runs print {"verdict": {"verdict": ...}, "boxes": N}.
                if isinstance(verdict, dict):
                    verdict = verdict.get("verdict")
                    s.setdefault("subproblems", s.get("boxes"))
                    # ... and x + y at the horizon as their first measure.
                    m = (s.get("measures") or [{}])[0]
                    enc, smp = m.get("enclosure"), m.get("sampled")
                    if enc:
                        s.setdefault("final_width", enc[1] - enc[0])
                    if smp:
                        s.setdefault("sampled_width", smp[1] - smp[0])
                    s.setdefault("width_ratio", m.get("ratio"))
                # CORA's time is for the full published horizon only.
                speedup = CORA_SECONDS / rec["wall"] if a.horizon == 20.0 else None
            else:
                verdict = rec["status"]
                speedup = None
            rec["cora_ratio"] = speedup
            print(f"{run:<12} {name:<30} {rec['wall']:>8.2f} {verdict:<9} "
                  f"{fmt(s.get('final_width'), 10, '.4f')} {fmt(s.get('sampled_width'), 10, '.4f')} "
                  f"{fmt(s.get('width_ratio'), 7, '.3f')} {fmt(s.get('subproblems'), 6, 'd')} "
                  f"{fmt(speedup, 10, '.0f')}{'x' if speedup else ' '}", flush=True)
            if s.get("reason") and verdict != "proved":
                print(f"{'':<10} reason: {s['reason']}")
            if rec.get("stderr"):
                print(f"{'':<10} error: {rec['stderr']}")
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump({"threads": a.threads, "timeout": a.timeout, "horizon": a.horizon,
                   "cora_seconds": CORA_SECONDS, "runs": results}, f, indent=2)
    print(f"wrote {os.path.join(a.out, 'results.json')}")
    # Exit status: 0 if every run finished (whatever its verdict), 1 otherwise.
    return 0 if all(r["status"] == "ok" for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())

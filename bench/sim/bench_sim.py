"""Simulation benchmark (issue: foundation): samara's tight mode against scipy.

Same work on both sides, single thread: the 9 published PID flights and N flights
(default 1000) from random y0 in [1.4286, 4.2857] with a constant ex = 0.187, plate6
model, 40 sample-and-hold periods of 0.5 integrated one by one. scipy: solve_ivp
DOP853, rtol 1e-10, atol 1e-12 on the independent Python model
(bench/model_reference/alsomitra.py). samara: `samara simulate --integrator tight`
(DOP853, same tolerances); its `wall_seconds` is the simulation time (file writing
excluded); the process time is printed too.

Usage: bench/.venv/bin/python bench/sim/bench_sim.py [--runs N]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
repo = os.path.dirname(os.path.dirname(here))
sys.path.insert(0, os.path.join(repo, "bench", "model_reference"))
import alsomitra as am  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--runs", type=int, default=1000)
args = ap.parse_args()

subprocess.run(["cargo", "build", "--release", "-q", "-p", "samara-cli"], cwd=repo, check=True)
samara = os.path.join(repo, "target", "release", "samara")
env = dict(os.environ, RAYON_NUM_THREADS="1")

rng = np.random.default_rng(2025)
y0s = rng.uniform(1.4286, 4.2857, args.runs)
pid_starts = [(0.1 + n * 0.025) / 0.07 for n in range(9)]


def run_samara(extra):
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        out = subprocess.run([samara, "simulate", "--integrator", "tight", "--no-plot", "--json", "--out", d] + extra,
                             check=True, capture_output=True, text=True, env=env)
        proc = time.perf_counter() - t
        js = json.loads(out.stdout)
        finals = [[s["final_state"][k] for k in ("v_xp", "v_yp", "omega", "theta", "x", "y")] for s in js["starts"]]
        return js["wall_seconds"], proc, np.array(finals)


def run_scipy(starts, ctl):
    integ = am.solve_ivp_integrator("DOP853", 1e-10, 1e-12)
    t = time.perf_counter()
    finals = [am.fly("plate6", y0, ctl, integ)[-1][0][:6] for y0 in starts]
    return time.perf_counter() - t, np.array(finals)


s_pid, p_pid, f_pid = run_samara([])
py_pid, g_pid = run_scipy(pid_starts, "pid")
s_c, p_c, f_c = run_samara(["--controller", "constant:0.187", "--y0", ",".join(repr(float(v)) for v in y0s)])
py_c, g_c = run_scipy(y0s, 0.187)

print(f"{'work':<28}{'scipy s':>10}{'samara s':>11}{'ratio':>9}{'samara proc s':>15}{'max |dev|':>12}")
print(f"{'9 PID flights':<28}{py_pid:>10.3f}{s_pid:>11.4f}{py_pid / s_pid:>8.0f}x{p_pid:>15.3f}{np.max(np.abs(f_pid - g_pid)):>12.1e}")
print(f"{f'{args.runs} constant-ex flights':<28}{py_c:>10.3f}{s_c:>11.4f}{py_c / s_c:>8.0f}x{p_c:>15.3f}{np.max(np.abs(f_c - g_c)):>12.1e}")

"""Writes golden files for samara's Rust tests from the independent Python model.

- crates/samara-plant/tests/data/rhs_reference.json: per variant, states, ex, and the
  right-hand side computed by alsomitra.py.
- crates/samara-sim/tests/data/flight_reference.json: per variant, closed-loop flights
  integrated by scipy solve_ivp (DOP853, rtol 1e-12, atol 1e-14): state at each control
  instant.
Also prints how well this Python model reproduces ../shared/reference/Training_Data.csv.
Usage: bench/.venv/bin/python bench/model_reference/make_golden.py
"""
import json
import os
import sys

import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
import alsomitra as am  # noqa: E402

repo = os.path.dirname(os.path.dirname(here))
rng = np.random.default_rng(42)

rhs_ref = {}
for variant in ["plate6", "reduced", "full"]:
    cases = []
    for k in range(30):
        s = [rng.uniform(0.8, 1.5), rng.uniform(-0.6, 0.3), rng.uniform(-0.5, 0.5), rng.uniform(-1.2, 0.3),
             rng.uniform(0, 40), rng.uniform(-40, 5), rng.uniform(-0.2, 0.2)]
        if k == 0:
            s = [1.0, 0.0, 0.0, 0.0, 0.0, 1.4285714285714286, 0.0]
        if k == 1:
            s[1] = 0.0
        if k == 2:
            s[2] = 0.0
        if k in (3, 4):
            s[1] = abs(s[1]) + 0.05  # alpha > 0
        if variant == "reduced":
            s = s[:6]
        ex = float(rng.uniform(0.181, 0.193))
        cases.append({"state": s, "ex": ex, "rhs": [float(v) for v in am.rhs(variant, s, ex)]})
    rhs_ref[variant] = cases
os.makedirs(os.path.join(repo, "crates/samara-plant/tests/data"), exist_ok=True)
with open(os.path.join(repo, "crates/samara-plant/tests/data/rhs_reference.json"), "w") as f:
    json.dump({"source": "bench/model_reference/alsomitra.py (independent numpy implementation of MODEL.md)", "cases": rhs_ref}, f, indent=1)

integ = am.solve_ivp_integrator("DOP853", 1e-12, 1e-14)
flights = []
for variant, ctl in [("plate6", "pid"), ("full", "pid"), ("plate6", 0.187), ("reduced", 0.187), ("full", 0.187)]:
    for y0 in [1.4285714285714286, 4.285714285714286]:
        rows = am.fly(variant, y0, ctl, integ)
        flights.append({"model": variant, "controller": ctl, "y0": y0,
                        "states": [[float(v) for v in s] for s, _ in rows], "ex": [e for _, e in rows]})
os.makedirs(os.path.join(repo, "crates/samara-sim/tests/data"), exist_ok=True)
with open(os.path.join(repo, "crates/samara-sim/tests/data/flight_reference.json"), "w") as f:
    json.dump({"source": "bench/model_reference/alsomitra.py + scipy solve_ivp DOP853 rtol 1e-12 atol 1e-14", "flights": flights}, f)

# How well does this independent model + scipy reproduce the published data?
ref = np.loadtxt(os.path.join(repo, "..", "shared", "reference", "Training_Data.csv"), delimiter=",")
integ10 = am.solve_ivp_integrator("DOP853", 1e-10, 1e-12)
rows = []
for n in range(9):
    y0 = (0.1 + n * 0.025) / 0.07
    rows += [list(s[:6]) + [e] for s, e in am.fly("plate6", y0, "pid", integ10)]
print("python model + solve_ivp DOP853 (1e-10/1e-12) vs Training_Data.csv: max abs dev %.3e" % np.max(np.abs(np.array(rows) - ref)))

"""Verifier benchmark (issue: verifier): the P1-P4 critical-value table, side by side.

- samara: `samara critical` (exact branch and bound with sound LP bounds), the sum of the
  reported times for P1-P4.
- HiGHS (highspy): a plain big-M MILP per property (and per disjunct), big-M constants
  from interval bounds, maximising/minimising x + y: the same critical values (a
  cross-check) and its time.
- Marabou (maraboupy): what the published pipeline does, a scan of yes/no queries over
  ystar (bisection to 1e-3 on P1), and its time.

Networks: the published base/adversarial 6-6-4-1 (normalised units) and a 6-64-32-1 ReLU
network trained by samara (`samara train --arch 6,64,32,1`, raw units).
Usage: bench/.venv/bin/python bench/verify/bench_verify.py
"""
import json
import os
import subprocess
import tempfile
import time

import numpy as np
import onnx
from onnx import numpy_helper

here = os.path.dirname(os.path.abspath(__file__))
repo = os.path.dirname(os.path.dirname(here))
ref = os.path.join(repo, "..", "shared", "reference")
spec = os.path.join(repo, "models", "alsomitra", "alsomitra.spec")
subprocess.run(["cargo", "build", "--release", "-q", "-p", "samara-cli"], cwd=repo, check=True)
samara = os.path.join(repo, "target", "release", "samara")
C = np.array([0.967568147, -0.607397104, -0.356972794, -0.96847853, 0.482420778, -41.68140527])
S = np.array([2.522324921, 0.564375713, 0.406153017, 0.900476013, 41.23229622, 45.87863879])


def layers_of(path):
    """Affine layers (W, b) and whether inputs/outputs are normalised, from a Gemm/Relu
    ONNX graph (samara's export or the published files)."""
    m = onnx.load(path)
    init = {t.name: numpy_helper.to_array(t).astype(np.float64) for t in m.graph.initializer}
    layers, pre, post = [], None, None
    for n in m.graph.node:
        if n.op_type == "Gemm":
            W = init[n.input[1]]
            tb = any(a.name == "transB" and a.i == 1 for a in n.attribute)
            W = W if tb else W.T  # rows = outputs
            layers.append((W, init[n.input[2]]))
        elif n.op_type in ("Sub", "Div", "Mul", "Add"):
            c = init.get(n.input[1])
            if not layers:
                pre = (pre or []) + [(n.op_type, c)]
            else:
                post = (post or []) + [(n.op_type, c)]
    return layers, pre, post


def affine_in(pre):
    """raw -> network-input map as (scale, shift): z = scale * raw + shift."""
    sc, sh = np.ones(6), np.zeros(6)
    for op, c in pre or []:
        if op == "Sub":
            sh = sh - c
        elif op == "Div":
            sc, sh = sc / c, sh / c
        elif op == "Mul":
            sc, sh = sc * c, sh * c
        elif op == "Add":
            sh = sh + c
    return sc, sh


def affine_out(post):
    a, b = 1.0, 0.0
    for op, c in post or []:
        c = float(np.ravel(c)[0])
        if op == "Mul":
            a, b = a * c, b * c
        elif op == "Add":
            b = b + c
    return a, b


def milp(path, units_norm, prop, disjunct):
    """Big-M MILP with HiGHS; returns the optimum of x + y (max for P1, -(x+y) max for P2,
    min for P3/P4)."""
    import highspy

    layers, pre, post = layers_of(path)
    isc, ish = affine_in(pre)
    oa, ob = affine_out(post)
    if units_norm:  # the published _norm files: raw = C + S z, ex = 0.181 + 0.012 out
        isc, ish, oa, ob = 1.0 / S, -C / S, 0.012, 0.181
    lo_raw, hi_raw = C, C + S
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    inf = highspy.kHighsInf
    # Raw inputs as variables.
    xs = [h.getNumCol() + i for i in range(6)]
    for i in range(6):
        h.addVar(lo_raw[i], hi_raw[i])
    # z0 = isc * raw + ish (interval bounds propagate).
    lo = np.minimum(isc * lo_raw + ish, isc * hi_raw + ish)
    hi = np.maximum(isc * lo_raw + ish, isc * hi_raw + ish)
    prev, plo, phi = xs, lo, hi
    first = True
    for k, (W, b) in enumerate(layers):
        zlo = np.zeros(len(b))
        zhi = np.zeros(len(b))
        zs = []
        for r in range(len(b)):
            w = W[r] * (isc if first else 1.0)
            c = b[r] + (float(W[r] @ ish) if first else 0.0)
            zlo[r] = c + np.sum(np.minimum(w * plo, w * phi)) if not first else c + np.sum(np.minimum(w * lo_raw, w * hi_raw))
            zhi[r] = c + np.sum(np.maximum(w * plo, w * phi)) if not first else c + np.sum(np.maximum(w * lo_raw, w * hi_raw))
            j = h.getNumCol()
            h.addVar(-inf, inf)
            idx = [j] + list(prev)
            val = [1.0] + list(-w)
            h.addRow(c, c, len(idx), np.array(idx, dtype=np.int32), np.array(val))
            zs.append(j)
        first = False
        # ReLU on every layer (the published networks and samara's have it on the output).
        a_s = []
        for r, z in enumerate(zs):
            l, u = zlo[r] - 1e-6, zhi[r] + 1e-6
            a = h.getNumCol()
            h.addVar(0.0, max(u, 0.0))
            if l >= 0:
                h.addRow(0, 0, 2, np.array([a, z], dtype=np.int32), np.array([1.0, -1.0]))
            elif u <= 0:
                h.addRow(0, 0, 1, np.array([a], dtype=np.int32), np.array([1.0]))
            else:
                d = h.getNumCol()
                h.addVar(0.0, 1.0)
                h.changeColIntegrality(d, highspy.HighsVarType.kInteger)
                h.addRow(0, inf, 2, np.array([a, z], dtype=np.int32), np.array([1.0, -1.0]))  # a >= z
                h.addRow(-inf, -l, 3, np.array([a, z, d], dtype=np.int32), np.array([1.0, -1.0, -l]))  # a <= z - l(1-d)
                h.addRow(-inf, 0, 2, np.array([a, d], dtype=np.int32), np.array([1.0, -u]))  # a <= u d
            a_s.append(a)
        prev, plo, phi = a_s, np.maximum(zlo, 0), np.maximum(zhi, 0)
    out = prev[0]
    # ex = oa * out + ob.
    def ex_row(lo_, hi_):
        h.addRow(lo_ - ob, hi_ - ob, 1, np.array([out], dtype=np.int32), np.array([oa]))
    xy = np.array([xs[4], xs[5]], dtype=np.int32)
    if prop == "p1":
        ex_row(-inf, 0.187)
        h.changeColsCost(2, xy, np.array([1.0, 1.0]))
        h.changeObjectiveSense(highspy.ObjSense.kMaximize)
    elif prop == "p2":
        ex_row(0.187, inf)
        h.changeColsCost(2, xy, np.array([-1.0, -1.0]))
        h.changeObjectiveSense(highspy.ObjSense.kMaximize)
    else:
        if prop == "p3":
            h.addRow(-0.786, -0.747, 1, np.array([xs[3]], dtype=np.int32), np.array([1.0]))
            ex_row(*((-inf, 0.184) if disjunct == 0 else (0.19, inf)))
        else:
            h.addRow(-inf, -0.12, 1, np.array([xs[2]], dtype=np.int32), np.array([1.0]))
            h.addRow(-inf, -0.3, 1, np.array([xs[1]], dtype=np.int32), np.array([1.0]))
            ex_row(0.187, inf)
        t = h.getNumCol()
        h.addVar(0.0, inf)
        h.addRow(0, inf, 3, np.array([t, xs[4], xs[5]], dtype=np.int32), np.array([1.0, -1.0, -1.0]))  # t >= x+y
        if prop == "p3":
            h.addRow(0, inf, 3, np.array([t, xs[4], xs[5]], dtype=np.int32), np.array([1.0, 1.0, 1.0]))  # t >= -(x+y)
        else:
            h.addRow(0, inf, 2, np.array([xs[4], xs[5]], dtype=np.int32), np.array([1.0, 1.0]))  # x + y >= 0
        h.changeColsCost(1, np.array([t], dtype=np.int32), np.array([1.0]))
        h.changeObjectiveSense(highspy.ObjSense.kMinimize)
    h.run()
    if h.getModelStatus() != highspy.HighsModelStatus.kOptimal:
        return None
    return h.getInfo().objective_function_value


def marabou_scan(path, units_norm, lo_y=0.0, hi_y=100.0, tol=1e-3):
    """P1 by bisection over ystar with one Marabou query per step (the published way)."""
    from maraboupy import Marabou

    opts = Marabou.createOptions(verbosity=0, timeoutInSeconds=120)
    calls = 0

    def violated(ystar):
        nonlocal calls
        calls += 1
        net = Marabou.read_onnx(path)
        iv, ov = net.inputVars[0].flatten(), net.outputVars[0].flatten()
        for i in range(6):
            lo, hi = (0.0, 1.0) if units_norm else (C[i], C[i] + S[i])
            net.setLowerBound(iv[i], lo)
            net.setUpperBound(iv[i], hi)
        # x + y >= ystar  ->  -(x + y) <= -ystar, in the input's units.
        if units_norm:
            net.addInequality([iv[4], iv[5]], [-S[4], -S[5]], -ystar + C[4] + C[5])
            net.addInequality([ov[0]], [0.012], 0.187 - 0.181 - 1e-9)
        else:
            net.addInequality([iv[4], iv[5]], [-1.0, -1.0], -ystar)
            net.addInequality([ov[0]], [1.0], 0.187 - 1e-9)
        res = net.solve(options=opts, verbose=False)
        return res[0] == "sat"

    lo, hi = lo_y, hi_y
    t = time.perf_counter()
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if violated(mid):
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi), time.perf_counter() - t, calls


def samara_table(path, spec_path):
    vals, secs = {}, 0.0
    for p in ["p1", "p2", "p3", "p4"]:
        out = subprocess.run([samara, "critical", spec_path, "--property", p, "--param", "ystar", "--network", f"f={path}", "--json"],
                             check=True, capture_output=True, text=True)
        v = json.loads(out.stdout)
        vals[p] = v["critical"]
        secs += v["seconds"]
    return vals, secs


tmp = tempfile.mkdtemp()
# A 6-64-32-1 network trained by samara on its own regenerated data (raw units).
subprocess.run([samara, "simulate", "--out", tmp, "--no-plot"], check=True, capture_output=True)
big = os.path.join(tmp, "big.onnx")
subprocess.run([samara, "train", "--data", os.path.join(tmp, "training_data.csv"), "--arch", "6,64,32,1", "--epochs", "200", "--out", big],
               check=True, capture_output=True)
raw_spec = os.path.join(tmp, "raw.spec")
with open(spec) as f:
    text = f.read()
text = "\n".join(l for l in text.splitlines() if not l.startswith("normalise") and not l.strip().startswith("range") and not l.strip().startswith("dataset"))
text = "\n".join(l for l in text.splitlines() if "p5" not in l)
with open(raw_spec, "w") as f:
    f.write(text + "\n")

rows = []
for name, path, norm, sp in [("base_model_norm (6-6-4-1)", os.path.join(ref, "base_model_norm.onnx"), True, spec),
                             ("adversarial_model_norm (6-6-4-1)", os.path.join(ref, "adversarial_model_norm.onnx"), True, spec),
                             ("samara 6-64-32-1 (raw)", big, False, raw_spec)]:
    vals, s_secs = samara_table(path, sp)
    t = time.perf_counter()
    m = {"p1": milp(path, norm, "p1", 0), "p2": milp(path, norm, "p2", 0),
         "p3": min(v for v in [milp(path, norm, "p3", 0), milp(path, norm, "p3", 1)] if v is not None),
         "p4": milp(path, norm, "p4", 0)}
    h_secs = time.perf_counter() - t
    agree = all(abs((vals[p] or 0) - (m[p] or 0)) <= 1e-4 * (1 + abs(m[p] or 0)) for p in vals)
    try:
        mar_v, mar_secs, calls = marabou_scan(path, norm)
    except Exception as e:  # maraboupy's ONNX parser rejects some graphs
        print(f"Marabou could not run on {name}: {type(e).__name__}: {str(e).splitlines()[0][:120]}")
        mar_v, mar_secs, calls = float("nan"), float("nan"), 0
    rows.append((name, s_secs, h_secs, mar_secs, calls, agree, vals, m, mar_v))

print(f"{'network':<34}{'samara s':>10}{'HiGHS MILP s':>14}{'ratio':>8}{'Marabou P1 scan s':>19}{'calls':>7}{'ratio':>8}  values agree")
for name, s, hs, ms, calls, agree, vals, m, mv in rows:
    print(f"{name:<34}{s:>10.3f}{hs:>14.3f}{hs / s:>7.0f}x{ms:>19.2f}{calls:>7}{ms / s:>7.0f}x  {agree}")
    print(f"    samara {vals}\n    HiGHS  {m}\n    Marabou P1 scan {mv:.4f}")

#!/usr/bin/env python3
"""Evaluate every ONNX network of VNN-COMP benchmark folders with samara and with
onnxruntime on random inputs, and report the largest relative error.

samara's side is `cargo run --release -p samara-nn --example onnx_eval`, which prints
the graph evaluation (`g`) and the lowered chain the verifier reads (`c`) per input.
Inputs are uniform in [lo, hi] (default [0, 1], the image range), float32 (the same
float32 values go to both). With --spec-box, each input is drawn instead from the box of
one of the benchmark's properties of the network, taken at random (the `*instances.csv`
in the network's folder or up to two above it; its first 50 properties of that
network): the region verification covers. [0, 1] alone can miss a network's working range (nn4sys's
learned indexes read keys up to 2.6e6 and output 0 on [0, 1]; collins_rul_cnn's ReLUs
are all off there), which makes the comparison vacuous; the `out spread` column (the
largest max - min of an output over the inputs) shows whether the outputs moved.
Relative error: |samara - ort| / max(1, |ort|).

usage: check_onnx.py [--n 100] [--tol 1e-5] [--spec-box] [--samara BIN] NET_OR_DIR...
Exit 1 if any network disagrees beyond --tol or fails to import.
"""
import argparse, glob, gzip, os, re, subprocess, sys, tempfile, time

import numpy as np
import onnx
import onnxruntime as ort

ort.set_default_logger_severity(3)


def nets_of(paths):
    for p in paths:
        if os.path.isdir(p):
            fs = sorted(glob.glob(os.path.join(p, "**", "*.onnx"), recursive=True))
            fs += sorted(glob.glob(os.path.join(p, "**", "*.onnx.gz"), recursive=True))
            yield from fs
        else:
            yield p


def plain(path, tmp):
    if path.endswith(".gz"):
        out = os.path.join(tmp, os.path.basename(path)[:-3])
        with gzip.open(path, "rb") as f, open(out, "wb") as g:
            g.write(f.read())
        return out
    return path


def open_text(path):
    return gzip.open(path, "rt") if path.endswith(".gz") else open(path)


BOUND = re.compile(r"\(\s*(<=|>=)\s+X_(\d+)\s+([-+0-9.eE]+)\s*\)")


def spec_boxes(net_path, n_in, max_props=50):
    """The input boxes of the benchmark's properties of `net_path` (per property, the
    smallest box holding its input constraints), as a list of (lo, hi) arrays; None
    when no instances.csv lists the network."""
    d = os.path.dirname(os.path.abspath(net_path))
    base = os.path.basename(net_path)
    base = base[:-3] if base.endswith(".gz") else base
    for up in range(3):
        for csv in sorted(glob.glob(os.path.join(d, "*instances.csv"))):
            props = []
            for line in open(csv):
                parts = [p.strip() for p in line.split(",")]
                if len(parts) >= 2 and os.path.basename(parts[0]).replace(".gz", "") == base:
                    props.append(os.path.join(d, parts[1]))
            if not props:
                continue
            boxes = []
            for prop in props[:max_props]:
                if not os.path.exists(prop) and os.path.exists(prop + ".gz"):
                    prop += ".gz"
                lo = np.full(n_in, np.inf)
                hi = np.full(n_in, -np.inf)
                for op, i, v in BOUND.findall(open_text(prop).read()):
                    i, v = int(i), float(v)
                    if i < n_in:
                        if op == ">=":
                            lo[i] = min(lo[i], v)
                        else:
                            hi[i] = max(hi[i], v)
                if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo <= hi):
                    boxes.append((lo, hi))
            return boxes or None
        d = os.path.dirname(d)
    return None


def input_shape(model):
    inits = {i.name for i in model.graph.initializer}
    ins = [i for i in model.graph.input if i.name not in inits]
    dims = [d.dim_value if d.dim_value > 0 else 1 for d in ins[0].type.tensor_type.shape.dim]
    if len(dims) >= 2:
        dims[0] = 1
    dtype = np.float64 if ins[0].type.tensor_type.elem_type == onnx.TensorProto.DOUBLE else np.float32
    return ins[0].name, dims, dtype


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("paths", nargs="+")
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--tol", type=float, default=1e-5)
    ap.add_argument("--lo", type=float, default=0.0)
    ap.add_argument("--hi", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--spec-box", action="store_true", help="inputs from the properties' boxes (see the docs)")
    ap.add_argument("--samara", default=None, help="onnx_eval binary (default: cargo run)")
    a = ap.parse_args()
    cmd = [a.samara] if a.samara else ["cargo", "run", "-q", "--release", "-p", "samara-nn", "--example", "onnx_eval", "--"]
    rng = np.random.default_rng(a.seed)
    bad = 0
    print("| network | inputs | outputs | input range | out spread | graph max rel err | chain max rel err | chain layers / note | samara s |")
    print("|---|---|---|---|---|---|---|---|---|", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for path in nets_of(a.paths):
            f = plain(path, tmp)
            model = onnx.load(f)
            name, shape, dtype = input_shape(model)
            sess = ort.InferenceSession(f, providers=["CPUExecutionProvider"])
            n_in = int(np.prod(shape))
            boxes = spec_boxes(path, n_in) if a.spec_box else None
            if boxes is None:
                xs = rng.uniform(a.lo, a.hi, size=(a.n, n_in)).astype(np.float32)
                rng_text = f"[{a.lo:g}, {a.hi:g}]"
            else:
                # Each input from one property's box, taken at random.
                pick = rng.integers(len(boxes), size=a.n)
                xs = np.stack([rng.uniform(*boxes[k]) for k in pick]).astype(np.float32)
                rng_text = f"{len(boxes)} spec boxes in [{xs.min():.4g}, {xs.max():.4g}]"
            ys = np.stack([sess.run(None, {name: x.reshape(shape).astype(dtype)})[0].reshape(-1) for x in xs]).astype(np.float64)
            csv = os.path.join(tmp, "x.csv")
            np.savetxt(csv, xs.astype(np.float64), delimiter=",", fmt="%.9g")
            t0 = time.time()
            r = subprocess.run(cmd + [f, csv], capture_output=True, text=True)
            dt = time.time() - t0
            note = " ".join(l for l in r.stderr.strip().splitlines() if l)[:300]
            if r.returncode != 0:
                print(f"| {os.path.basename(path)} | {xs.shape[1]} | {ys.shape[1]} | {rng_text} | - | import failed | - | {note} | {dt:.1f} |")
                bad += 1
                continue
            g = np.array([[float(v) for v in l.split(",")[1:]] for l in r.stdout.splitlines() if l.startswith("g,")])
            c = np.array([[float(v) for v in l.split(",")[1:]] for l in r.stdout.splitlines() if l.startswith("c,")])
            def rel(s):
                if s.shape != ys.shape:
                    return float("inf")
                return float(np.max(np.abs(s - ys) / np.maximum(1.0, np.abs(ys))))
            eg = rel(g)
            ec = rel(c) if len(c) else None
            if eg > a.tol or (ec is not None and ec > a.tol):
                bad += 1
            ecs = f"{ec:.2e}" if ec is not None else "not lowered"
            spread = float(np.max(ys.max(axis=0) - ys.min(axis=0)))
            print(f"| {os.path.basename(path)} | {xs.shape[1]} | {ys.shape[1]} | {rng_text} | {spread:.3g} | {eg:.2e} | {ecs} | {note} | {dt:.1f} |", flush=True)
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()

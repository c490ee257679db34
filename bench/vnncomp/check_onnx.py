#!/usr/bin/env python3
"""Evaluate every ONNX network of VNN-COMP benchmark folders with samara and with
onnxruntime on random inputs, and report the largest relative error.

samara's side is `cargo run --release -p samara-nn --example onnx_eval`, which prints
the graph evaluation (`g`) and the lowered chain the verifier reads (`c`) per input.
Inputs are uniform in [lo, hi] (default [0, 1], the image range), float32 (the same
float32 values go to both). Relative error: |samara - ort| / max(1, |ort|).

usage: check_onnx.py [--n 100] [--tol 1e-5] [--samara BIN] NET_OR_DIR...
Exit 1 if any network disagrees beyond --tol or fails to import.
"""
import argparse, glob, gzip, os, subprocess, sys, tempfile, time

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
    ap.add_argument("--samara", default=None, help="onnx_eval binary (default: cargo run)")
    a = ap.parse_args()
    cmd = [a.samara] if a.samara else ["cargo", "run", "-q", "--release", "-p", "samara-nn", "--example", "onnx_eval", "--"]
    rng = np.random.default_rng(a.seed)
    bad = 0
    print("| network | inputs | outputs | graph max rel err | chain max rel err | chain layers / note | samara s |")
    print("|---|---|---|---|---|---|---|", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for path in nets_of(a.paths):
            f = plain(path, tmp)
            model = onnx.load(f)
            name, shape, dtype = input_shape(model)
            sess = ort.InferenceSession(f, providers=["CPUExecutionProvider"])
            xs = rng.uniform(a.lo, a.hi, size=(a.n, int(np.prod(shape)))).astype(np.float32)
            ys = np.stack([sess.run(None, {name: x.reshape(shape).astype(dtype)})[0].reshape(-1) for x in xs]).astype(np.float64)
            csv = os.path.join(tmp, "x.csv")
            np.savetxt(csv, xs.astype(np.float64), delimiter=",", fmt="%.9g")
            t0 = time.time()
            r = subprocess.run(cmd + [f, csv], capture_output=True, text=True)
            dt = time.time() - t0
            note = " ".join(l for l in r.stderr.strip().splitlines() if l)[:300]
            if r.returncode != 0:
                print(f"| {os.path.basename(path)} | {xs.shape[1]} | {ys.shape[1]} | import failed | - | {note} | {dt:.1f} |")
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
            print(f"| {os.path.basename(path)} | {xs.shape[1]} | {ys.shape[1]} | {eg:.2e} | {ecs} | {note} | {dt:.1f} |", flush=True)
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()

"""Reference outputs of onnxruntime for every published ONNX network.

Writes crates/samara-nn/tests/data/<network>.csv: 1000 seeded random inputs (float32
values, so onnxruntime and samara read the same numbers) and onnxruntime's outputs.
samara's test `onnx_reference` compares its own f64 evaluation with them.

Usage: bench/.venv/bin/python bench/nn/onnx_expected.py [REFERENCE_DIR]
"""
import os
import sys

import numpy as np
import onnxruntime as ort

here = os.path.dirname(os.path.abspath(__file__))
repo = os.path.dirname(os.path.dirname(here))
ref = sys.argv[1] if len(sys.argv) > 1 else os.path.join(repo, "..", "shared", "reference")
out_dir = os.path.join(repo, "crates", "samara-nn", "tests", "data")
os.makedirs(out_dir, exist_ok=True)

consts = np.loadtxt(os.path.join(ref, "Normalisation_Constants.csv"), delimiter=",")
lo_raw, span_raw = consts[0, :6], consts[1, :6]

for name in sorted(os.listdir(ref)):
    if not name.endswith(".onnx"):
        continue
    sess = ort.InferenceSession(os.path.join(ref, name), providers=["CPUExecutionProvider"])
    inp = sess.get_inputs()[0]
    n_in = inp.shape[-1]
    rng = np.random.default_rng(20251122)
    u = rng.uniform(-0.1, 1.1, size=(1000, n_in))
    if "denorm" in name:
        x = lo_raw + u * span_raw  # raw units, slightly beyond the data box
    else:
        x = u
    x = x.astype(np.float32)
    ys = np.concatenate([sess.run(None, {inp.name: x[i : i + 1]})[0] for i in range(len(x))])
    path = os.path.join(out_dir, name.replace(".onnx", ".csv"))
    with open(path, "w") as f:
        f.write(f"# onnxruntime {ort.__version__}; columns: {n_in} inputs then {ys.shape[1]} outputs\n")
        for xi, yi in zip(x, ys):
            f.write(",".join(repr(float(v)) for v in list(xi) + list(yi)) + "\n")
    print(f"{name}: wrote {path}")

"""Check an ONNX file exported by samara against samara's own outputs with onnxruntime.

Usage: check_export.py MODEL.onnx DATA.csv   (DATA: rows of inputs then samara outputs)
Exit 0 if every output agrees to 1e-6 relative to max(1, |y|); prints the worst error.
"""
import sys

import numpy as np
import onnxruntime as ort

model, data = sys.argv[1], sys.argv[2]
sess = ort.InferenceSession(model, providers=["CPUExecutionProvider"])
inp = sess.get_inputs()[0]
n_in = inp.shape[-1]
rows = np.loadtxt(data, delimiter=",", ndmin=2)
dtype = np.float64 if inp.type == "tensor(double)" else np.float32
worst = 0.0
for r in rows:
    y = sess.run(None, {inp.name: r[:n_in].astype(dtype).reshape(1, -1)})[0].ravel()
    ref = r[n_in:]
    worst = max(worst, float(np.max(np.abs(y - ref) / np.maximum(1.0, np.abs(ref)))))
print(f"max relative |onnxruntime - samara| = {worst:.3e} over {len(rows)} inputs")
sys.exit(0 if worst <= 1e-6 else 1)

"""samara from Python, notebook style: the case study's headline numbers, then a
network trained in PyTorch a minute ago, verified exactly.

    python python/examples/notebook.py     # from the repository root, or
    python notebook.py                     # from python/examples: any folder works

The paths are found from this file's own place, not the current folder: the
repository is two folders up, the spec is models/alsomitra/alsomitra.spec in it, and
the published files are in ../shared/reference beside the checkout (or in
$SAMARA_REFERENCE). Needs the ``samara`` wheel (docs/python.md) and numpy; the PyTorch
part runs when torch is installed and is skipped (with a message) otherwise. Every cell
checks what it prints, so the script exits non-zero when a number is off. Results are
typed: ``r.verdict == "proved"``, ``r.final_x_plus_y`` a numpy array.
"""

import os
import sys
import time
from pathlib import Path

import numpy as np

import samara

ROOT = Path(__file__).resolve().parents[2]
REF = Path(os.environ.get("SAMARA_REFERENCE", ROOT.parent / "shared" / "reference"))
SPEC = ROOT / "models" / "alsomitra" / "alsomitra.spec"

# %% 1. The specification, stated once in physical units (docs/spec.md).
spec = samara.Spec(SPEC)
print("properties:", spec.properties)

# %% 2. P1's critical value for the published naive network: the smallest ystar for
# which "y >= -x + ystar => ex >= 0.187" holds on the network's domain. The paper's
# Table 1 gives 45.912 for it; samara adds that it is vacuous (no input of the domain
# satisfies the premise at that ystar).
base = samara.Network.from_onnx(REF / "base_model_norm.onnx")
t = time.perf_counter()
p1 = spec.critical(property="p1", param="ystar", networks={"f": base})
print(f"P1 critical ystar = {p1.critical:.6f} (vacuous: {p1.vacuous}, "
      f"holds {p1.holds}) in {time.perf_counter() - t:.3f} s")
assert abs(p1.critical - 45.912) < 5e-4 and p1.vacuous and p1.complete

# %% 3. The adversarially trained controller in closed loop: reduced plate model, the
# published starts y0 in [0.1, 0.3] m / 0.07 m, goal |x + y| <= 2 at t = 20.
adv = samara.Network.from_onnx(REF / "adversarial_model_denorm.onnx")
t = time.perf_counter()
r = samara.reach(adv, goal_ystar=2.0)
lo, hi = r.final_x_plus_y
print(f"reach: {r.verdict}, x + y at t = 20 in [{lo:.4f}, {hi:.4f}], "
      f"{r.subproblems} sub-boxes, {time.perf_counter() - t:.2f} s")
assert r.verdict == "proved" and -2.0 <= lo <= hi <= 2.0
# The enclosure contains the sampled flights the run made (reach.json's own samples).
slo, shi = r.sampled_x_plus_y
assert lo <= slo <= shi <= hi

# %% 4. A 6-6-4-1 ReLU network trained in PyTorch on the published data (normalised
# inputs and output, ReLU on the output unit as published), handed over in memory.
try:
    import torch
except ImportError:
    print("torch is not installed: skipping the PyTorch part (pip install torch)")
    sys.exit(0)

data = samara.read_table(REF / "Training_Data_Normalised.csv")
X = torch.tensor(data[:, :6], dtype=torch.float32)
Y = torch.tensor(data[:, 6:7], dtype=torch.float32)


def fit(seed: int) -> "torch.nn.Sequential":
    torch.manual_seed(seed)
    m = torch.nn.Sequential(
        torch.nn.Linear(6, 6), torch.nn.ReLU(),
        torch.nn.Linear(6, 4), torch.nn.ReLU(),
        torch.nn.Linear(4, 1), torch.nn.ReLU(),
    )
    opt = torch.optim.Adam(m.parameters(), lr=0.01)
    for _ in range(1500):
        opt.zero_grad()
        loss = torch.mean((m(X) - Y) ** 2)
        loss.backward()
        opt.step()
    return m


t = time.perf_counter()
for seed in range(10):  # a ReLU output unit can die; take the first live network
    model = fit(seed)
    with torch.no_grad():
        pred = model(X)
    r2 = 1.0 - float(torch.sum((pred - Y) ** 2) / torch.sum((Y - Y.mean()) ** 2))
    if r2 > 0.5:
        break
print(f"torch: seed {seed}, R^2 = {r2:.3f}, {time.perf_counter() - t:.1f} s")
assert r2 > 0.5

net = samara.Network.from_torch(model)
with torch.no_grad():
    assert np.allclose(net.eval(data[:, :6]), model(X).double().numpy(), atol=1e-5)

# %% 5. Its P1-P4 critical values, exact; each checked against PyTorch itself: no
# sampled point where the premise holds above the critical ystar violates the
# conclusion, and the witness, evaluated by torch, sits at the threshold.
lo_in = np.array([0.967568147, -0.607397104, -0.356972794, -0.96847853, 0.482420778, -41.68140527])
rng_in = np.array([2.522324921, 0.564375713, 0.406153017, 0.900476013, 41.23229622, 45.87863879])
dom_hi = np.array([3.489893068, -0.043021391, 0.049180223, -0.068002517, 41.714716998, 4.19723352])
pts = lo_in + np.random.default_rng(0).random((200_000, 6)) * (dom_hi - lo_in)
with torch.no_grad():
    ex = 0.181 + 0.012 * model(torch.tensor((pts - lo_in) / rng_in, dtype=torch.float32)).double().numpy()[:, 0]
for prop in ["p1", "p2", "p3", "p4"]:
    t = time.perf_counter()
    c = spec.critical(property=prop, param="ystar", networks={"f": net})
    print(f"{prop}: holds {c.holds}, critical ystar = {c.critical}, vacuous: {c.vacuous}, "
          f"{time.perf_counter() - t:.3f} s")
    assert c.complete, c.unknown_reason
    if prop == "p1" and c.critical is not None:
        s = pts[:, 5] + pts[:, 4]  # y + x
        bad = (s >= c.critical + 1e-6) & (ex < 0.187 - 1e-6)
        assert not bad.any(), pts[bad][:3]
    if prop == "p2" and c.critical is not None:
        s = -(pts[:, 5] + pts[:, 4])  # y <= -x - ystar  <=>  -(x + y) >= ystar
        bad = (s >= c.critical + 1e-6) & (ex > 0.187 + 1e-6)
        assert not bad.any(), pts[bad][:3]
    w = c.witness_values
    if w:
        z = np.array([[w[k] for k in spec.networks["f"][0]]])
        with torch.no_grad():
            ew = 0.181 + 0.012 * float(model(torch.tensor((z - lo_in) / rng_in, dtype=torch.float32)))
        print(f"    witness {w} -> torch ex = {ew:.6f}")
print("all checks passed")

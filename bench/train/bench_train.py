"""Training benchmark (issue: networks): samara against PyTorch (CPU) on the published
trainings: 6-6-4-1 MLP with ReLU on every layer, Adam lr 0.06, batch 50, 1000 epochs,
10% test split, min-max normalised Training_Data.csv; `plain` (MSE) and `adversarial`
(FGSM, eps 0.005 in normalised units, clean and adversarial rows together).

samara is timed as a whole process (`samara train ... --json`, data loading and ONNX
export included); PyTorch as the training loop only (data already in tensors). Both
single-threaded. Prints seconds, the ratio and each side's test R^2.

Usage: bench/.venv/bin/python bench/train/bench_train.py [--epochs N]
"""
import argparse
import json
import os
import subprocess
import tempfile
import time

import numpy as np
import torch

here = os.path.dirname(os.path.abspath(__file__))
repo = os.path.dirname(os.path.dirname(here))
data_path = os.path.join(repo, "..", "shared", "reference", "Training_Data.csv")
ap = argparse.ArgumentParser()
ap.add_argument("--epochs", type=int, default=1000)
args = ap.parse_args()

torch.set_num_threads(1)
subprocess.run(["cargo", "build", "--release", "-q", "-p", "samara-cli"], cwd=repo, check=True)
samara = os.path.join(repo, "target", "release", "samara")

raw = np.loadtxt(data_path, delimiter=",")
lo, span = raw.min(0), raw.max(0) - raw.min(0)
z = (raw - lo) / span
rng = np.random.default_rng(0)
idx = rng.permutation(len(z))
test, train = idx[:36], idx[36:]
X, Y = torch.tensor(z[train, :6], dtype=torch.float32), torch.tensor(z[train, 6:], dtype=torch.float32)
Xt, Yt = torch.tensor(z[test, :6], dtype=torch.float32), torch.tensor(z[test, 6:], dtype=torch.float32)


def torch_train(adversarial):
    torch.manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Linear(6, 6), torch.nn.ReLU(), torch.nn.Linear(6, 4), torch.nn.ReLU(),
                              torch.nn.Linear(4, 1), torch.nn.ReLU())
    opt = torch.optim.Adam(net.parameters(), lr=0.06)
    lossf = torch.nn.MSELoss()
    t = time.perf_counter()
    for _ in range(args.epochs):
        perm = torch.randperm(len(X))
        for k in range(0, len(X), 50):
            b = perm[k:k + 50]
            xb, yb = X[b], Y[b]
            if adversarial:
                xa = xb.clone().requires_grad_(True)
                g, = torch.autograd.grad(lossf(net(xa), yb), xa)
                xb = torch.cat([xb, (xb + 0.005 * g.sign()).detach()])
                yb = torch.cat([yb, yb])
            opt.zero_grad()
            lossf(net(xb), yb).backward()
            opt.step()
    secs = time.perf_counter() - t
    with torch.no_grad():
        pred = net(Xt).numpy().ravel() * span[6] + lo[6]
    truth = Yt.numpy().ravel() * span[6] + lo[6]
    r2 = 1 - np.mean((pred - truth) ** 2) / np.var(truth)
    return secs, r2


def samara_train(method):
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        out = subprocess.run([samara, "train", "--data", data_path, "--method", method, "--epochs", str(args.epochs),
                              "--out", os.path.join(d, "n.onnx"), "--json"], check=True, capture_output=True, text=True)
        secs = time.perf_counter() - t
    return secs, json.loads(out.stdout)["r2"]


print(f"{'training':<26}{'PyTorch s':>10}{'samara s':>10}{'ratio':>8}{'R^2 torch':>11}{'R^2 samara':>12}")
for name, method, adv in [("plain (published)", "plain", False), ("adversarial FGSM", "adversarial", True)]:
    ts, tr2 = torch_train(adv)
    ss, sr2 = samara_train(method)
    print(f"{name:<26}{ts:>10.3f}{ss:>10.3f}{ts / ss:>7.0f}x{tr2:>11.4f}{sr2:>12.4f}")

#!/usr/bin/env python3
"""Dump one ACAS Xu instance (network + property) as the text that
`cargo run --release -p samara-bounds --example box_bench FILE` reads, so that a change of
samara-bounds' search can be timed after building that crate alone (about a minute)
instead of the whole application.

Usage: bench/vnncomp/dump_box.py NETWORK.onnx PROPERTY.vnnlib OUT.txt
Handles the ACAS Xu shapes only: a chain of MatMul/Add/Relu after `input - AvgImg`, an input
box, and one conjunction of `(<= Y_a Y_b)`, `(>= Y_a Y_b)`, `(<= Y_a c)`, `(>= Y_a c)`
(properties with a disjunction, 6-10 of them, are refused).

Format: the number of maps; per map `inp out relu`, the weights row by row (out x inp), the
biases; then the number of cases; per case the lower ends, the upper ends, the number of
constraints, and per constraint `c_0 .. c_{m-1} d strict` for `c . y + d <= 0`.
"""
import re
import sys

import numpy as np
import onnx
from onnx import numpy_helper


def main():
    net, prop, out = sys.argv[1:4]
    m = onnx.load(net)
    init = {i.name: numpy_helper.to_array(i).astype(np.float64) for i in m.graph.initializer}
    avg = init["input_AvgImg"].reshape(-1)
    ws = [n.input[1] for n in m.graph.node if n.op_type == "MatMul"]
    bs = [n.input[1] for n in m.graph.node if n.op_type == "Add"]
    lines = [str(len(ws))]
    for k, (wn, bn) in enumerate(zip(ws, bs)):
        w, b = init[wn], init[bn].reshape(-1)
        if k == 0:
            b = b - avg @ w
        inp, o = w.shape
        lines.append(f"{inp} {o} {int(k < len(ws) - 1)}")
        lines.append(" ".join(repr(float(v)) for v in w.T.reshape(-1)))
        lines.append(" ".join(repr(float(v)) for v in b))
    txt = re.sub(r";[^\n]*", "", open(prop).read())
    if "(or" in txt:
        sys.exit("dump_box.py: disjunctions are not handled")
    n = init[ws[0]].shape[0]
    no = init[ws[-1]].shape[1]
    lo, hi = [None] * n, [None] * n
    for op, v, val in re.findall(r"\(assert \((<=|>=) X_(\d+) ([-+\d.eE]+)\)\)", txt):
        (hi if op == "<=" else lo)[int(v)] = float(val)
    cons = []
    for op, a, b in re.findall(r"\(assert \((<=|>=) Y_(\d+) (Y_\d+|[-+\d.eE]+)\)\)", txt):
        c, d = [0.0] * no, 0.0
        s = 1.0 if op == "<=" else -1.0
        c[int(a)] += s
        if b.startswith("Y_"):
            c[int(b[2:])] -= s
        else:
            d = -s * float(b)
        cons.append(" ".join(map(repr, c)) + f" {d!r} 0")
    lines += ["1", " ".join(map(repr, lo)), " ".join(map(repr, hi)), str(len(cons))] + cons
    open(out, "w").write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()

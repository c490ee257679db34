#!/usr/bin/env python3
"""Dump one ACAS Xu instance (network + property) as the text that
`cargo run --release -p samara-bounds --example box_bench FILE` reads, so that a change of
samara-bounds' search can be timed after building that crate alone (about a minute)
instead of the whole application.

Usage: bench/vnncomp/dump_box.py NETWORK.onnx PROPERTY.vnnlib OUT.txt
Handles the ACAS Xu shapes only: a chain of MatMul/Add/Relu after `input - AvgImg`, an input
box, and a conjunction of `(<= Y_a Y_b)`, `(>= Y_a Y_b)`, `(<= Y_a c)`, `(>= Y_a c)`, or
`(assert (or (and ...) ...))` blocks whose conjunctions hold such constraints and input
bounds (properties 6-10: a case per combination of conjunctions, over the shared box
narrowed by their own bounds).

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
    n = init[ws[0]].shape[0]
    no = init[ws[-1]].shape[1]

    def parse(body, lo, hi):
        """Input bounds of `body` into lo/hi; its output constraints as dumped lines."""
        for op, v, val in re.findall(r"\((<=|>=) X_(\d+) ([-+\d.eE]+)\)", body):
            if op == "<=":
                hi[int(v)] = float(val) if hi[int(v)] is None else min(hi[int(v)], float(val))
            else:
                lo[int(v)] = float(val) if lo[int(v)] is None else max(lo[int(v)], float(val))
        cons = []
        for op, a, b in re.findall(r"\((<=|>=) Y_(\d+) (Y_\d+|[-+\d.eE]+)\)", body):
            c, d = [0.0] * no, 0.0
            s = 1.0 if op == "<=" else -1.0
            c[int(a)] += s
            if b.startswith("Y_"):
                c[int(b[2:])] -= s
            else:
                d = -s * float(b)
            cons.append(" ".join(map(repr, c)) + f" {d!r} 0")
        return cons

    # Each top-level `(assert ...)`, found by its balanced parentheses: plain ones are
    # shared by every case; an `(assert (or (and ...) ...))` multiplies the cases by its
    # conjunctions (property 6 has one over inputs and one over outputs).
    blocks, depth, start = [], 0, None
    for i, ch in enumerate(txt):
        if ch == "(":
            if depth == 0:
                start = i
            depth += 1
        elif ch == ")":
            depth -= 1
            if depth == 0:
                blocks.append(txt[start:i + 1])
    asserts = [b for b in blocks if b.startswith("(assert")]
    plain = " ".join(b for b in asserts if not re.match(r"\(assert\s*\(or", b))
    lo, hi = [None] * n, [None] * n
    shared = parse(plain, lo, hi)
    cases = [(lo, hi, shared)]
    for b in asserts:
        if not re.match(r"\(assert\s*\(or", b):
            continue
        ands = re.findall(r"\(and ((?:[^()]|\([^()]*\))*)\)", b)
        nxt = []
        for l0, h0, c0 in cases:
            for body in ands:
                l, h = list(l0), list(h0)
                nxt.append((l, h, c0 + parse(body, l, h)))
        cases = nxt
    lines.append(str(len(cases)))
    for l, h, cons in cases:
        lines += [" ".join(map(repr, l)), " ".join(map(repr, h)), str(len(cons))] + cons
    open(out, "w").write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()

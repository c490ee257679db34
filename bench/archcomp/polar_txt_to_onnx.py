#!/usr/bin/env python3
"""Convert a POLAR/Sherlock-style network text file (the TORA heterogeneous controllers
nn_tora_relu_tanh.txt and nn_tora_sigmoid.txt of verivital/ARCH-COMP2023) to ONNX, so that
samara (which reads ONNX only) can load it. Standard library only.

Text format (benchmarks/Tora_Heterogeneous/Specifications.txt): number of inputs, number of
outputs, number of hidden layers, the width of each hidden layer, then for every layer
(hidden layers, then the output layer) and every neuron of it: its weights (one per input of
the layer) followed by its bias; finally the output offset and the output scale. The
activations are not in the file, so they are given here:

    polar_txt_to_onnx.py nn_tora_relu_tanh.txt out.onnx --hidden relu --output tanh
    polar_txt_to_onnx.py nn_tora_sigmoid.txt out.onnx --hidden sigmoid --output sigmoid

The offset and scale are NOT folded into the network (the system file applies them, e.g.
`actuate u = 11 * net[0]` in examples/archcomp/tora_heterogeneous.sys); the script prints
them so they can be checked against the file.
"""
import argparse
import struct
import sys

ACTS = {"relu": "Relu", "tanh": "Tanh", "sigmoid": "Sigmoid", "linear": None}


def read_txt(path):
    vals = []
    with open(path) as f:
        for line in f:
            line = line.split("#")[0].strip()
            if line:
                vals.append(float(line))
    n_in, n_out, n_hidden = int(vals[0]), int(vals[1]), int(vals[2])
    widths = [int(v) for v in vals[3:3 + n_hidden]]
    pos = 3 + n_hidden
    sizes = [n_in] + widths + [n_out]
    layers = []
    for fan_in, fan_out in zip(sizes[:-1], sizes[1:]):
        w = [[0.0] * fan_out for _ in range(fan_in)]  # fan_in x fan_out (for x @ W)
        b = [0.0] * fan_out
        for j in range(fan_out):
            for i in range(fan_in):
                w[i][j] = vals[pos]
                pos += 1
            b[j] = vals[pos]
            pos += 1
        layers.append((w, b))
    rest = vals[pos:]
    if len(rest) != 2:
        sys.exit("%s: expected offset and scale after the weights, found %d numbers" % (path, len(rest)))
    return sizes, layers, rest[0], rest[1]


# --- minimal protobuf writer -------------------------------------------------------------
def varint(n):
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        if n:
            out.append(b | 0x80)
        else:
            out.append(b)
            return bytes(out)


def key(field, wire):
    return varint((field << 3) | wire)


def f_varint(field, n):
    return key(field, 0) + varint(n)


def f_bytes(field, data):
    if isinstance(data, str):
        data = data.encode()
    return key(field, 2) + varint(len(data)) + data


def tensor(name, dims, floats):
    # TensorProto: dims=1, data_type=2 (FLOAT=1), name=8, raw_data=9
    msg = b"".join(f_varint(1, d) for d in dims)
    msg += f_varint(2, 1) + f_bytes(8, name)
    msg += f_bytes(9, struct.pack("<%df" % len(floats), *floats))
    return msg


def value_info(name, dims):
    dim_msgs = b"".join(f_bytes(1, f_varint(1, d)) for d in dims)  # Dimension.dim_value=1
    shape = f_bytes(2, dim_msgs)  # TypeProto.Tensor.shape=2
    tensor_type = f_varint(1, 1) + shape  # elem_type=1 FLOAT
    type_proto = f_bytes(1, tensor_type)  # TypeProto.tensor_type=1
    return f_bytes(1, name) + f_bytes(2, type_proto)


def node(op, inputs, outputs, name):
    msg = b"".join(f_bytes(1, i) for i in inputs) + b"".join(f_bytes(2, o) for o in outputs)
    return msg + f_bytes(3, name) + f_bytes(4, op)


def build(sizes, layers, hidden, output):
    nodes, inits = [], []
    cur = "input"
    for k, (w, b) in enumerate(layers):
        fan_in, fan_out = len(w), len(b)
        inits.append(tensor("W%d" % k, [fan_in, fan_out], [v for row in w for v in row]))
        inits.append(tensor("B%d" % k, [fan_out], b))
        nodes.append(node("MatMul", [cur, "W%d" % k], ["mm%d" % k], "matmul%d" % k))
        nodes.append(node("Add", ["mm%d" % k, "B%d" % k], ["z%d" % k], "add%d" % k))
        cur = "z%d" % k
        act = ACTS[output if k == len(layers) - 1 else hidden]
        if act:
            nodes.append(node(act, [cur], ["a%d" % k], "act%d" % k))
            cur = "a%d" % k
    nodes.append(node("Identity", [cur], ["output"], "out"))
    graph = b"".join(f_bytes(1, n) for n in nodes) + f_bytes(2, "polar_txt")
    graph += b"".join(f_bytes(5, t) for t in inits)
    graph += f_bytes(11, value_info("input", [1, sizes[0]]))
    graph += f_bytes(12, value_info("output", [1, sizes[-1]]))
    opset = f_bytes(1, "") + f_varint(2, 13)
    model = f_varint(1, 7) + f_bytes(2, "samara polar_txt_to_onnx.py")
    model += f_bytes(7, graph) + f_bytes(8, opset)
    return model


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("txt")
    ap.add_argument("onnx")
    ap.add_argument("--hidden", choices=sorted(ACTS), required=True)
    ap.add_argument("--output", choices=sorted(ACTS), required=True)
    a = ap.parse_args()
    sizes, layers, offset, scale = read_txt(a.txt)
    with open(a.onnx, "wb") as f:
        f.write(build(sizes, layers, a.hidden, a.output))
    print("%s: layers %s, hidden %s, output %s; file's offset %g, scale %g (apply them in the .sys)"
          % (a.onnx, "-".join(map(str, sizes)), a.hidden, a.output, offset, scale))


if __name__ == "__main__":
    main()

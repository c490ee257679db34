"""samara.Network: import (path and bytes), evaluation against onnxruntime's outputs
(crates/samara-nn/tests/data, the same check as the Rust test onnx_reference.rs),
export round trip, errors."""

import pickle

import numpy as np
import pytest

import samara
from conftest import ROOT, reference

STEMS = [
    "base_model_norm",
    "adversarial_model_norm",
    "base_model_denorm",
    "adversarial_model_denorm",
    "merged_model_base",
]


def expected(stem):
    return np.loadtxt(ROOT / "crates" / "samara-nn" / "tests" / "data" / f"{stem}.csv", delimiter=",", comments="#")


@pytest.mark.parametrize("stem", STEMS)
def test_eval_agrees_with_onnxruntime(stem):
    net = samara.Network.from_onnx(reference(f"{stem}.onnx"))
    data = expected(stem)
    ni, no = net.n_inputs, net.n_outputs
    assert data.shape == (1000, ni + no)
    y = net.eval(data[:, :ni])
    assert y.shape == (1000, no) and y.dtype == np.float64
    rel = np.abs(y - data[:, ni:]) / np.maximum(1.0, np.abs(data[:, ni:]))
    assert rel.max() <= 1e-6


def test_bytes_path_single_row_and_round_trip():
    p = reference("base_model_denorm.onnx")
    a = samara.Network.from_onnx(p)
    b = samara.Network.from_onnx(p.read_bytes())
    x = expected("base_model_denorm")[:50, :6]
    assert np.array_equal(a.eval(x), b.eval(x))
    assert a.eval(x[0]).shape == (1,) and a.eval(x[0])[0] == a.eval(x)[0, 0]
    assert np.array_equal(a(x), a.eval(x))
    onnx = a.to_onnx()
    assert isinstance(onnx, bytes) and len(onnx) > 100
    c = samara.Network.from_onnx(onnx)
    assert (c.n_inputs, c.n_outputs) == (6, 1)
    # float32 tensors (the normalisation constants are rounded again): to 1e-6
    assert np.allclose(c.eval(x), a.eval(x), rtol=1e-6, atol=0)
    # float64 tensors (and pickling, which uses them): exact
    e = samara.Network.from_onnx(a.to_onnx(float64=True))
    assert np.array_equal(e.eval(x), a.eval(x))
    d = pickle.loads(pickle.dumps(a))
    assert np.array_equal(d.eval(x), a.eval(x))


def test_integer_and_fortran_inputs_are_converted():
    net = samara.Network.from_onnx(reference("base_model_norm.onnx"))
    x = np.asfortranarray(np.arange(12, dtype=np.int64).reshape(2, 6) % 2)
    assert np.array_equal(net.eval(x), net.eval(np.ascontiguousarray(x, dtype=float)))


def test_wrong_shapes_raise_value_error():
    net = samara.Network.from_onnx(reference("base_model_norm.onnx"))
    with pytest.raises(ValueError, match=r"expected \(n, 6\)"):
        net.eval(np.zeros((3, 5)))
    with pytest.raises(ValueError, match="5 values, expected 6"):
        net.eval(np.zeros(5))
    with pytest.raises(ValueError):
        net.eval(np.zeros((2, 3, 6)))


def test_missing_file_and_bad_bytes():
    with pytest.raises(FileNotFoundError):
        samara.Network.from_onnx("/nonexistent/net.onnx")
    with pytest.raises(ValueError):
        samara.Network.from_onnx(b"not an onnx file")


def test_from_torch_matches_torch_forward():
    """A PyTorch nn.Sequential handed over in memory (torch.onnx export) evaluates as
    torch does (to float32 rounding); a non-module is a ValueError."""
    torch = pytest.importorskip("torch")
    torch.manual_seed(1)
    m = torch.nn.Sequential(
        torch.nn.Linear(6, 16), torch.nn.ReLU(),
        torch.nn.Linear(16, 8), torch.nn.Tanh(),
        torch.nn.Linear(8, 3), torch.nn.Sigmoid(),
    )
    net = samara.Network.from_torch(m)
    assert (net.n_inputs, net.n_outputs) == (6, 3)
    x = np.random.default_rng(2).normal(size=(500, 6))
    with torch.no_grad():
        want = m(torch.tensor(x, dtype=torch.float32)).double().numpy()
    assert np.allclose(net.eval(x), want, atol=1e-5)
    assert m.training  # the module's mode is restored
    with pytest.raises(ValueError, match="torch.nn.Module"):
        samara.Network.from_torch(lambda v: v)


def test_non_finite_inputs_are_refused_naming_the_index():
    """Issue 35 item 8: NaN used to vanish in the ReLUs (0.1089 out of all-NaN inputs),
    +inf gave 0.1818 on the raw-unit network; None is NaN through numpy."""
    for stem, bad in [("base_model_norm", np.nan), ("base_model_denorm", np.inf)]:
        net = samara.Network.from_onnx(reference(f"{stem}.onnx"))
        with pytest.raises(ValueError, match=r"input \[0, 0\]"):
            net.eval(np.full(6, bad))
    net = samara.Network.from_onnx(reference("base_model_norm.onnx"))
    with pytest.raises(ValueError, match=r"input \[0, 0\]"):
        net.eval([None] * 6)
    x = np.full((3, 6), 0.5)
    x[2, 4] = -np.inf
    with pytest.raises(ValueError, match=r"input \[2, 4\]"):
        net.eval(x)
    # Finite rows still evaluate.
    assert np.isfinite(net.eval(np.full((3, 6), 0.5))).all()

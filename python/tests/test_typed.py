"""Issue 38: Python over the library's typed results. Results are frozen dataclasses
(fields in dir(), not assignable, short repr); long calls answer Ctrl-C; errors name the
Python argument; the .pyi stubs match the native module."""

import ast
import dataclasses
import os
import signal
import threading
import time
from pathlib import Path

import pytest

import samara
from samara import _samara
from conftest import SPEC, reference


@pytest.fixture(scope="module")
def net():
    return samara.Network.from_onnx(reference("base_model_norm.onnx"))


def test_verify_results_are_typed(net):
    (r,) = samara.Spec(SPEC).verify(networks={"f": net}, params={"ystar": 50}, property="p1")
    assert r.verdict == "proved" and r.property == "p1"
    assert {"property", "verdict", "counterexample", "seconds", "vacuous", "vacuity", "unknown_reason"} <= set(dir(r))
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.verdict = "violated"
    assert r.verdict == "proved"
    assert repr(r).startswith("VerifyResult(property='p1', verdict='proved', seconds=")
    assert len(repr(r)) < 120
    assert r["verdict"] == "proved" and r.as_dict()["verdict"] == "proved"


def test_critical_result_is_typed(net):
    c = samara.Spec(SPEC).critical(property="p1", param="ystar", networks={"f": net})
    assert c.holds == "above" and "threshold" in dir(c)
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.critical = 3
    assert abs(c.critical - 45.912) < 5e-4
    assert len(repr(c)) < 160, repr(c)
    assert isinstance(c.counterexample_range, tuple) and len(c.counterexample_range) == 2


def test_ctrl_c_interrupts_a_long_critical_call_within_a_second():
    # Without the signal this search runs to its 10 s limit (test_spec: 1 s of it leaves
    # it unknown).
    slow = samara.Network.from_onnx(reference("goedel_lipschitz_norm.onnx"))
    sent = {}

    def interrupt():
        time.sleep(1.0)
        sent["at"] = time.monotonic()
        os.kill(os.getpid(), signal.SIGINT)

    t = threading.Thread(target=interrupt)
    t.start()
    with pytest.raises(KeyboardInterrupt):
        samara.Spec(SPEC).critical(property="p1", param="ystar", networks={"f": slow}, timeout=10.0)
    took = time.monotonic() - sent["at"]
    t.join()
    assert took < 1.0, f"KeyboardInterrupt {took:.2f} s after SIGINT"


def test_errors_name_the_python_argument(net):
    spec = samara.Spec(SPEC)
    with pytest.raises(ValueError, match=r'networks\["g"\]'):
        spec.verify(networks={"g": net})
    with pytest.raises(ValueError, match=r'params\["ystar"\]'):
        spec.verify(networks={"f": net}, params={"ystar": float("nan")}, property="p1")
    with pytest.raises(ValueError) as e:
        spec.verify(networks={}, property="p1")
    assert 'networks={"f": Network}' in str(e.value) and "--network" not in str(e.value)


def test_integer_arguments_raise_named_errors(net):
    spec = samara.Spec(SPEC)
    with pytest.raises(OverflowError, match="max_nodes=-1"):
        spec.verify(networks={"f": net}, property="p1", max_nodes=-1)
    with pytest.raises(OverflowError, match="max_nodes="):
        spec.verify(networks={"f": net}, property="p1", max_nodes=2**70)
    with pytest.raises(TypeError, match="max_nodes=1.5"):
        spec.verify(networks={"f": net}, property="p1", max_nodes=1.5)
    with pytest.raises(TypeError, match=r"networks\['f'\]: expected samara.Network"):
        spec.verify(networks={"f": str(reference("base_model_norm.onnx"))})


def test_a_missing_spec_path_is_not_parsed_as_text(tmp_path):
    with pytest.raises(FileNotFoundError):
        samara.Spec(str(tmp_path / "missing.txt"))
    with pytest.raises(FileNotFoundError):
        samara.Spec("no/such/spec")
    # Text still parses.
    assert samara.Spec("network f(a) -> (b)\nproperty p: a >= 0 => b <= 1\n").properties == ["p"]


def test_samara_error_is_shown_as_samara_samara_error():
    assert samara.SamaraError.__module__ == "samara"
    assert samara.SamaraError.__qualname__ == "SamaraError"


def test_stubs_match_the_native_module():
    """Every public name of `samara._samara` is in `_samara.pyi` and every stub exists;
    for classes, the same methods and properties."""
    stub = ast.parse((Path(samara.__file__).parent / "_samara.pyi").read_text())
    stubbed = {}
    for node in stub.body:
        if isinstance(node, ast.ClassDef):
            stubbed[node.name] = {n.name for n in node.body if isinstance(n, ast.FunctionDef)}
        elif isinstance(node, ast.FunctionDef):
            stubbed[node.name] = None
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            stubbed[node.target.id] = None
    public = {k for k in dir(_samara) if not k.startswith("_") or k == "__version__"}
    assert public == set(stubbed), (public ^ set(stubbed))
    for name, members in stubbed.items():
        if members is None or name == "SamaraError":
            continue
        cls = getattr(_samara, name)
        real = {k for k in vars(cls) if not k.startswith("_") or k == "__init__"}
        if "__init__" in members:
            real.add("__init__")
        assert real == members, (name, real ^ members)


def test_reach_settings_name_the_network_and_threads_and_repr_is_short():
    path = reference("base_model_denorm.onnx")
    net = samara.Network.from_onnx(path)
    r = samara.reach(net, horizon=2.0, max_leaves=2, samples=5, threads=1)
    assert r.settings["network"] == str(path) and r.settings["threads"] == 1
    assert "verdict" in dir(r) and "leaves" in dir(r)
    assert len(repr(r)) < 300, len(repr(r))
    with pytest.raises(AttributeError):
        r.critical = 3
    with pytest.raises(OverflowError, match="threads=0"):
        samara.reach(net, horizon=2.0, threads=0)


def test_an_interval_of_three_values_is_refused():
    net = samara.Network.from_onnx(reference("base_model_denorm.onnx"))
    with pytest.raises(ValueError, match=r"y0=\(2.0, 5, 2.1\): give an interval"):
        samara.reach(net, y0=(2.0, 5, 2.1))
    with pytest.raises(ValueError, match=r"init\['theta'\]"):
        samara.reach(net, init={"theta": (0.0, 0.1, 0.2)})


def test_zero_pieces_is_a_named_error():
    root = Path(__file__).resolve().parents[2]
    net = samara.Network.from_onnx(root / "crates/samara-reach/tests/data/archcomp/controller_acc_5_20.onnx")
    with pytest.raises(OverflowError, match=r"grid\['x_lead'\]=0"):
        samara.reach_system(root / "examples/archcomp/acc.sys", net, grid={"x_lead": 0})


def test_reach_and_train_return_typed_values_not_json_text():
    """The native layer hands back the library's typed results as Python objects (no
    JSON text in between): `reach.json`'s fields, the training report with its log."""
    net = samara.Network.from_onnx(reference("base_model_denorm.onnx"))
    d = _samara.reach(net._net, "reduced", {"y": (2.0, 2.1)}, 2.0, 0.5, 50.0, None, True, 2, 5,
                      None, "n.onnx", 1)
    assert isinstance(d, dict) and d["verdict"] == {"verdict": "proved"}
    assert d["settings"]["network"] == "n.onnx" and isinstance(d["leaves"], list)
    assert isinstance(d["leaves"][0]["steps"][0]["bbox"][0][0], float)
    data = samara.read_table(reference("Training_Data.csv"))[:300]
    _, rep = samara.train(data, epochs=3, seed=1, min_r2=0.0)
    assert isinstance(rep, dict) and rep["log"].shape == (3, 3)
    assert all(set(r) == {"attempt", "seed", "epoch", "reason"} for r in rep["restart_log"])


def test_training_errors_name_the_python_argument():
    data = samara.read_table(reference("Training_Data.csv"))[:300]
    with pytest.raises(ValueError) as e:
        samara.train(data, epochs=0)
    assert "epochs 0 is out of range" in str(e.value) and "--" not in str(e.value), e.value
    with pytest.raises(ValueError) as e:
        samara.train(data, epochs=3, min_r2=1.5)
    assert "min_r2 1.5:" in str(e.value) and "--" not in str(e.value), e.value


def test_temporary_csv_names_are_not_shown(net):
    """A data set given as an array is written to a temporary CSV for the library; a
    message about it names the array (`datasets['train']`), not the file."""
    spec = samara.Spec(SPEC)
    bad = [[0.5] * 6 + [float("nan")]]
    with pytest.raises(ValueError) as e:
        spec.verify(networks={"f": net}, datasets={"train": bad}, property="p5")
    msg = str(e.value)
    assert "datasets['train']" in msg and "samara-train-" not in msg and ".csv" not in msg, msg

"""Issue 38: Python over the library's typed results. Results are frozen dataclasses
(fields in dir(), not assignable, short repr, numpy arrays where numbers form arrays);
long calls answer Ctrl-C; errors name the Python argument and count rows from 0; the
.pyi stubs match the native module, names and signatures."""

import ast
import dataclasses
import inspect
import math
import os
import subprocess
import sys
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import samara
import samara.distributed as sd  # noqa: E402
from samara import _samara
from conftest import ROOT, SPEC, reference


@pytest.fixture(scope="module")
def net():
    return samara.Network.from_onnx(reference("base_model_norm.onnx"))


def test_verify_results_are_typed(net):
    (r,) = samara.Spec(SPEC).verify(networks={"f": net}, params={"ystar": 50}, property="p1")
    assert r.verdict == "proved" and r.property == "p1"
    assert {"property", "verdict", "counterexample", "seconds", "vacuous", "vacuity", "unknown_reason"} <= set(dir(r))
    with pytest.raises(dataclasses.FrozenInstanceError, match=r"VerifyResult.verdict: a result is read-only"):
        r.verdict = "violated"
    assert r.verdict == "proved"
    assert repr(r).startswith("VerifyResult(property='p1', verdict='proved', seconds=")
    assert len(repr(r)) < 120
    assert r.as_dict()["verdict"] == "proved"
    with pytest.raises(TypeError):
        r["verdict"]  # attributes only: one way to read a field


def test_critical_result_is_typed(net):
    c = samara.Spec(SPEC).critical(property="p1", param="ystar", networks={"f": net})
    assert c.holds == "above" and "threshold" in dir(c)
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.critical = 3
    assert abs(c.critical - 45.912) < 5e-4
    assert len(repr(c)) < 160, repr(c)
    assert isinstance(c.counterexample_range, tuple) and len(c.counterexample_range) == 2


def test_ctrl_c_interrupts_a_long_verify_call_within_a_second():
    # The 360 p5_lipschitz queries take about 10 s here (release wheel); P1's critical
    # value on goedel_lipschitz_norm, this test's call before, now ends in about 0.2 s.
    slow = samara.Network.from_onnx(reference("adversarial_model_norm.onnx"))
    sent = {}

    def interrupt():
        time.sleep(1.0)
        sent["at"] = time.monotonic()
        os.kill(os.getpid(), signal.SIGINT)

    t = threading.Thread(target=interrupt)
    t.start()
    with pytest.raises(KeyboardInterrupt):
        samara.Spec(SPEC).verify(networks={"f": slow}, property="p5_lipschitz", timeout=60.0)
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


def _stub_params(fn: ast.FunctionDef) -> list:
    """(name, has a default) of a stub's parameters, without self."""
    a = fn.args
    pos = a.posonlyargs + a.args
    defaults = [False] * (len(pos) - len(a.defaults)) + [True] * len(a.defaults)
    out = [(p.arg, d) for p, d in zip(pos, defaults)]
    out += [(p.arg, d is not None) for p, d in zip(a.kwonlyargs, a.kw_defaults)]
    return [p for p in out if p[0] != "self"]


def _native_params(obj) -> list:
    sig = inspect.signature(obj)
    return [(n, p.default is not inspect.Parameter.empty) for n, p in sig.parameters.items()
            if n not in ("self", "$self")]


def test_stubs_match_the_native_module():
    """Every public name of `samara._samara` is in `_samara.pyi` and every stub exists;
    for classes, the same methods and properties; for every function, method and
    constructor, the same parameters in the same order, with defaults in the same
    places (from the module's own text signatures)."""
    stub = ast.parse((Path(samara.__file__).parent / "_samara.pyi").read_text())
    stubbed = {}
    funcs = {}
    for node in stub.body:
        if isinstance(node, ast.ClassDef):
            stubbed[node.name] = {n.name for n in node.body if isinstance(n, ast.FunctionDef)}
            for n in node.body:
                if isinstance(n, ast.FunctionDef) and not any(
                    isinstance(d, ast.Name) and d.id == "property" for d in n.decorator_list
                ):
                    funcs[(node.name, n.name)] = _stub_params(n)
        elif isinstance(node, ast.FunctionDef):
            stubbed[node.name] = None
            funcs[(None, node.name)] = _stub_params(node)
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
    checked = 0
    for (cls, name), params in funcs.items():
        if cls == "SamaraError":
            continue
        if cls is None:
            native = getattr(_samara, name)
        elif name == "__init__":
            native = getattr(_samara, cls)  # the constructor's signature is the class's
        else:
            native = getattr(getattr(_samara, cls), name)
        assert _native_params(native) == params, (cls, name, _native_params(native), params)
        checked += 1
    assert checked == 15  # 3 of Network, 3 of Spec (its constructor included), 9 functions


def test_reach_settings_name_the_network_and_threads_and_repr_is_short():
    path = reference("base_model_denorm.onnx")
    net = samara.Network.from_onnx(path)
    r = samara.reach(net, horizon=2.0, max_leaves=2, samples=5, threads=1)
    assert r.settings.network == str(path) and r.settings.threads == 1
    assert "verdict" in dir(r) and "leaves" in dir(r)
    assert len(repr(r)) < 300, len(repr(r))
    with pytest.raises(AttributeError, match="ReachResult.critical: a result is read-only"):
        r.critical = 3
    with pytest.raises(AttributeError, match="ReachSettings.threads: a result is read-only"):
        r.settings.threads = 4
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
    JSON text in between): `reach.json`'s fields, the training report with its log; the
    package turns them into its result classes."""
    net = samara.Network.from_onnx(reference("base_model_denorm.onnx"))
    d = _samara.reach(net._net, "reduced", {"y": (2.0, 2.1)}, 2.0, 0.5, 50.0, None, True, 2, 5,
                      None, "n.onnx", 1)
    assert isinstance(d, dict) and d["verdict"] == {"verdict": "proved"}
    assert d["settings"]["network"] == "n.onnx" and isinstance(d["leaves"], list)
    assert isinstance(d["leaves"][0]["steps"][0]["bbox"][0][0], float)
    r = samara.ReachResult._of(d)
    assert r.verdict == "proved" and r.settings.network == "n.onnx"
    data = samara.read_table(reference("Training_Data.csv"))[:300]
    _, rep = samara.train(data, epochs=3, seed=1, min_r2=0.0)
    assert isinstance(rep, samara.TrainReport) and rep.log.shape == (3, 3)
    assert all(isinstance(r, samara.Restart) for r in rep.restart_log)


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


TORA = ROOT / "examples" / "archcomp" / "tora.sys"
TORA_NET = ROOT / "crates" / "samara-reach" / "tests" / "data" / "archcomp" / "controller_tora.onnx"
TORA_KW = dict(order=3, network_error="symbolic:20", samples=16)


def _typed_values(obj, seen=None):
    """`obj` and every result nested in its fields (lists and dicts included)."""
    if isinstance(obj, samara._Typed):
        yield obj
        for f in dataclasses.fields(obj):
            yield from _typed_values(getattr(obj, f.name))
    elif isinstance(obj, (list, tuple)):
        for x in obj:
            yield from _typed_values(x)
    elif isinstance(obj, dict):
        for x in obj.values():
            yield from _typed_values(x)


def test_every_result_is_a_frozen_typed_value(net):
    """Each result the package returns, and each result nested in one, is a frozen
    dataclass: every field an attribute listed by dir(), assignment refused naming the
    field, a short repr, no dict behind it, numpy float64 arrays where the type says
    array, and equal to itself after a pickle round trip (Ray ships them)."""
    import pickle

    ctl = samara.Network.from_onnx(reference("base_model_denorm.onnx"))
    data = samara.read_table(reference("Training_Data_Normalised.csv"))[:5]
    spec = samara.Spec(SPEC)
    reach_kw = dict(horizon=1.0, max_leaves=2, samples=5, goal_ystar=5.0)
    parts = [samara.reach(ctl, y0=y, **reach_kw) for y in [(2.0, 2.05), (2.05, 2.1)]]
    results = {
        "verify (violated)": spec.verify(networks={"f": net}, params={"ystar": 40}, property="p1")[0],
        "critical": spec.critical(property="p1", param="ystar", networks={"f": net}),
        "robustness": samara.robustness(net, data, eps=[1e-3], lipschitz=[1e-2]),
        "simulate": samara.simulate(controller=ctl, y0=[2.0], horizon=1.0)[0],
        "reach": parts[0],
        "merge_reach": sd.merge_reach(parts),
        "train": samara.train(samara.read_table(reference("Training_Data.csv"))[:200], epochs=2, min_r2=0.0)[1],
        "reach_system": samara.reach_system(TORA, samara.Network.from_onnx(TORA_NET), **TORA_KW),
    }
    assert results["verify (violated)"].verdict == "violated"
    assert results["verify (violated)"].counterexample.point[0].network == "f"
    kinds = set()
    for what, r in results.items():
        for v in _typed_values(r):
            kinds.add(type(v).__name__)
            assert dataclasses.is_dataclass(v) and not hasattr(v, "_d"), (what, v)
            names = [f.name for f in dataclasses.fields(v)]
            assert set(names) <= set(dir(v)), (what, set(names) - set(dir(v)))
            assert list(v.as_dict()) == names
            assert len(repr(v)) < 200, (what, repr(v))
            name = names[0]
            with pytest.raises(dataclasses.FrozenInstanceError, match=rf"{type(v).__name__}\.{name}: a result is read-only"):
                setattr(v, name, None)
            hints = {f.name: str(f.type) for f in dataclasses.fields(v)}
            for k, t in hints.items():
                if t == "np.ndarray":
                    a = getattr(v, k)
                    assert isinstance(a, np.ndarray) and a.dtype == np.float64, (what, k)
            assert pickle.loads(pickle.dumps(v)) == v, what
    assert {"VerifyResult", "VerifyCounterexample", "NetworkPoint", "CriticalResult", "RobustnessResult",
            "RobustnessCell", "RobustnessPoint", "Flight", "ReachResult", "ReachSettings", "ReachGoal",
            "ReachLeaf", "MergedReach", "TrainReport", "SystemReachResult", "SystemLeaf"} <= kinds, kinds


def test_non_finite_numbers_cross_the_native_layer_as_floats():
    """Results reach Python by serde, not as JSON text: an unbounded end stays -inf (a
    JSON document would have written null), both ways through the grid merge."""
    ctl = samara.Network.from_onnx(TORA_NET)
    r = samara.reach_system(TORA, ctl, grid={"x1": 1}, **TORA_KW)
    assert r.cells == (0, 1) and r.instants.dtype == np.float64
    inst = r.instants.copy()
    inst[0, 0, 0] = -math.inf
    m = sd.merge_reach_system([dataclasses.replace(r, instants=inst)])
    assert m.instants[0, 0, 0] == -math.inf
    assert np.array_equal(m.instants[1:], r.instants[1:])


def test_errors_count_rows_from_0_and_name_the_array():
    net = samara.Network.from_onnx(reference("base_model_norm.onnx"))
    data = samara.read_table(reference("Training_Data_Normalised.csv"))[:3].copy()
    data[1, 2] = math.nan
    with pytest.raises(ValueError, match=r"data: row 1 column 2 is NaN"):
        samara.robustness(net, data)
    with pytest.raises(ValueError) as e:
        samara.Spec(SPEC).verify(networks={"f": net}, datasets={"train": data}, property="p5")
    msg = str(e.value)
    assert "datasets['train'] row 1" in msg and ".csv" not in msg, msg


def test_a_path_where_a_network_is_expected_is_a_named_type_error():
    path = reference("base_model_denorm.onnx")
    with pytest.raises(TypeError, match=r"network=.*expected samara.Network \(a path: load it with samara.Network.from_onnx"):
        samara.reach(str(path))
    with pytest.raises(TypeError, match=r"network=.*expected samara.Network"):
        samara.robustness(path, np.zeros((2, 7)))
    with pytest.raises(TypeError, match=r"network=.*expected samara.Network"):
        samara.reach_system(TORA, str(TORA_NET))
    with pytest.raises(TypeError, match=r"controller=.*a path; pass samara.Network.from_onnx"):
        samara.simulate(controller=str(path))


def test_zero_pieces_of_a_partition_is_a_named_error():
    net = samara.Network.from_onnx(reference("base_model_denorm.onnx"))
    with pytest.raises(OverflowError, match=r"pieces=0"):
        sd.reach_partition(net, pieces=0, local=True)


def _interrupt_after(seconds: float, sent: dict) -> threading.Thread:
    def run():
        time.sleep(seconds)
        sent["at"] = time.monotonic()
        os.kill(os.getpid(), signal.SIGINT)

    t = threading.Thread(target=run)
    t.start()
    return t


@pytest.mark.parametrize("call", ["reach", "train"])
def test_ctrl_c_interrupts_reach_and_train_within_a_second(call):
    """Not only the verifier: a reach run (about 4 s here) and a training run (about 6 s)
    raise KeyboardInterrupt within a second of SIGINT too."""
    if call == "reach":
        net = samara.Network.from_onnx(reference("base_model_denorm.onnx"))
        work = lambda: samara.reach(net, horizon=4.0)  # noqa: E731
    else:
        data = samara.read_table(reference("Training_Data.csv"))
        work = lambda: samara.train(data, epochs=20_000, min_r2=0.0)  # noqa: E731
    sent: dict = {}
    t = _interrupt_after(0.5, sent)
    with pytest.raises(KeyboardInterrupt):
        work()
    took = time.monotonic() - sent["at"]
    t.join()
    assert took < 1.0, f"KeyboardInterrupt {took:.2f} s after SIGINT"


def test_reach_system_takes_the_flows_time_order_and_step_tol_as_the_cli_does(tmp_path):
    """``time_order`` and ``step_tol`` are ``samara reach --time-order`` and ``--step-tol``:
    the same sets as the CLI's run with those flags (its reach.json), other sets than the
    defaults' (the flags reach the flow), and out-of-range values named as the CLI names
    them."""
    from test_spec import cli

    ctl = samara.Network.from_onnx(TORA_NET)
    fast = samara.reach_system(TORA, ctl, time_order=8, step_tol=1e-5, **TORA_KW)
    default = samara.reach_system(TORA, ctl, **TORA_KW)
    assert fast.verdict == default.verdict == "proved"
    assert fast.instants.shape == default.instants.shape
    assert not np.array_equal(fast.instants, default.instants)
    with pytest.raises(ValueError, match=r"time_order 9: give 1 to 8"):
        samara.reach_system(TORA, ctl, time_order=9, **TORA_KW)
    with pytest.raises(ValueError, match=r"step_tol 0.5: give a share of the set's width in \(0, 0.01\]"):
        samara.reach_system(TORA, ctl, step_tol=0.5, **TORA_KW)
    exe = cli()
    if exe is None:
        pytest.skip("the samara CLI is not built (cargo build --release -p samara-cli)")
    out = tmp_path / "r"
    subprocess.run(
        [exe, "reach", "--system", str(TORA), "--network", str(TORA_NET), "--order", "3",
         "--network-error", "symbolic:20", "--samples", "16", "--time-order", "8", "--step-tol", "1e-5",
         "--out", str(out)],
        check=True, capture_output=True, text=True,
    )
    import json

    d = json.loads((out / "reach.json").read_text())
    assert np.array_equal(np.array(d["result"]["instants"], dtype=np.float64), fast.instants)

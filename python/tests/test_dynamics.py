"""samara.simulate and samara.reach: shapes, the closed loop's physics (the glider
lands near y = -x), and agreement with the CLI (`samara simulate --json`, `samara
reach --json`) on the same work when the binary is available."""

import json
import subprocess

import numpy as np
import pytest

import samara
from conftest import ROOT, reference
from test_spec import cli


@pytest.fixture(scope="module")
def ctl():
    return samara.Network.from_onnx(reference("base_model_denorm.onnx"))


def test_simulate_shapes_and_controllers(ctl):
    fs = samara.simulate(controller=ctl, y0=[2.0, 3.0])
    assert len(fs) == 2
    f = fs[0]
    assert f.state_names == ["v_xp", "v_yp", "omega", "theta", "x", "y", "E"]
    assert f.t.shape == (2001,) and f.states.shape == (2001, 7) and f.ex.shape == (2001,)
    assert f.t[0] == 0.0 and abs(f.t[-1] - 20.0) < 1e-9 and f.initial[5] == 2.0
    assert np.all((f.ex >= 0.181) & (f.ex <= 0.193))
    # The network controller steers onto y = -x (|x + y| small at the end).
    assert abs(f.final_state["x"] + f.final_state["y"]) < 3.0
    pid = samara.simulate()  # the nine published starts, PID
    assert len(pid) == 9
    const = samara.simulate(controller=0.187, y0=[2.0], horizon=5.0)
    assert np.all(const[0].ex == 0.187)
    red = samara.simulate(model="reduced", controller=ctl, y0=[2.0], integrator="rk4", horizon=1.0)
    assert red[0].states.shape[1] == 6


def test_simulate_matches_cli(ctl, tmp_path):
    exe = cli()
    if exe is None:
        pytest.skip("the samara CLI is not built")
    out = subprocess.run(
        [exe, "simulate", "--controller", str(reference("base_model_denorm.onnx")), "--y0", "2,3",
         "--out", str(tmp_path / "sim"), "--json", "--no-plot"],
        check=True, capture_output=True, text=True, cwd=ROOT,
    )
    c = json.loads(out.stdout)
    fs = samara.simulate(controller=ctl, y0=[2.0, 3.0])
    for f, s in zip(fs, c["starts"]):
        assert f.y0 == s["y0"]
        assert f.final_state == s["final_state"]
        assert f.rhs_evals == s["rhs_evals"]


def test_simulate_errors(ctl):
    with pytest.raises(ValueError, match="unknown model"):
        samara.simulate(model="plate7")
    with pytest.raises(ValueError, match="unknown integrator"):
        samara.simulate(integrator="euler")
    with pytest.raises(ValueError, match="filter state E"):
        samara.simulate(model="reduced", controller="pid")
    with pytest.raises(ValueError, match="outside the allowed range"):
        samara.simulate(controller=0.5)
    with pytest.raises(ValueError, match="period"):
        samara.simulate(period=0.0)
    with pytest.raises(ValueError, match="a controller needs 6 raw inputs"):
        samara.simulate(controller=samara.Network.from_onnx(reference("merged_model_base.onnx")))


def test_reach_short_horizon(ctl):
    r = samara.reach(ctl, y0=(2.0, 2.1), horizon=2.0, goal_ystar=5.0)
    assert r.verdict == "proved" and r.proved and r.reason is None and r.counterexample is None
    assert r.t.shape == (5,) and np.allclose(r.t, [0, 0.5, 1, 1.5, 2])
    assert r.bbox.shape == (5, 6, 2) and np.all(r.bbox[..., 0] <= r.bbox[..., 1])
    assert r.bbox[0, 5, 0] <= 2.0 and r.bbox[0, 5, 1] >= 2.1
    assert np.allclose(r.x_plus_y[-1], r.final_x_plus_y)
    # sampled trajectories lie inside the enclosure
    lo, hi = r.sampled_x_plus_y
    assert r.final_x_plus_y[0] <= lo <= hi <= r.final_x_plus_y[1]
    assert np.isnan(r.ex[-1]).all() and np.all(r.ex[:-1, 0] <= r.ex[:-1, 1])


def test_reach_matches_cli(ctl, tmp_path):
    exe = cli()
    if exe is None:
        pytest.skip("the samara CLI is not built")
    out = subprocess.run(
        [exe, "reach", "--network", str(reference("base_model_denorm.onnx")), "--y0", "2:2.1",
         "--horizon", "2", "--goal-ystar", "5", "--out", str(tmp_path / "reach"), "--json"],
        capture_output=True, text=True, cwd=ROOT,
    )
    assert out.returncode == 0, out.stderr
    c = json.loads(out.stdout)
    r = samara.reach(ctl, y0=(2.0, 2.1), horizon=2.0, goal_ystar=5.0)
    assert r.final_x_plus_y.tolist() == c["final_x_plus_y"]
    assert r.sampled_x_plus_y.tolist() == c["sampled_x_plus_y"]
    assert r.subproblems == c["subproblems"] and r.verdict == c["verdict"]
    # Every sub-box's enclosures, bit for bit as the CLI's reach.json has them (where
    # the JSON writes an unbounded end as null, the typed result keeps the float).
    full = json.loads((tmp_path / "reach" / "reach.json").read_text())
    assert len(r.leaves) == len(full["leaves"])

    def arr(v):
        return np.array([[np.nan if x is None else x for x in iv] for iv in v], dtype=np.float64)

    for leaf, j in zip(r.leaves, full["leaves"]):
        assert np.array_equal(leaf.init, arr(j["init"])) and leaf.params == j["params"]
        assert leaf.failure == j["failure"] and list(leaf.flow_steps) == j["flow_steps"]
        assert leaf.t.tolist() == [s["t"] for s in j["steps"]]
        for k, s in enumerate(j["steps"]):
            assert np.array_equal(leaf.bbox[k], arr(s["bbox"]), equal_nan=True)
            assert np.array_equal(leaf.x_plus_y[k], arr([s["x_plus_y"]])[0], equal_nan=True)
            assert np.array_equal(leaf.x_plus_y_period[k], arr([s["x_plus_y_period"]])[0], equal_nan=True)
            ex = [np.nan, np.nan] if s["ex"] is None else s["ex"]
            assert np.array_equal(leaf.ex[k], np.array(ex), equal_nan=True)
    assert r.settings.as_dict() == {**full["settings"], "goal": {"ystar": 5.0, "from_": None},
                                    "init": {k: tuple(v) for k, v in full["settings"]["init"].items()},
                                    "clip": tuple(full["settings"]["clip"]), "network": r.settings.network}


def test_reach_errors(ctl):
    with pytest.raises(ValueError, match="unknown state"):
        samara.reach(ctl, init={"phi": (0, 1)})
    with pytest.raises(ValueError, match="multiple"):
        samara.reach(ctl, horizon=1.2, period=0.5)
    with pytest.raises(ValueError, match="goal_from"):
        samara.reach(ctl, goal_from=1.0)


def test_train_matches_cli(tmp_path):
    data = samara.read_table(reference("Training_Data.csv"))
    net, rep = samara.train(data, method="plain", epochs=15, seed=3, min_r2=0.0)
    assert (net.n_inputs, net.n_outputs) == (6, 1)
    assert rep.log.shape[1] == 3 and rep.log.shape[0] >= 1
    assert isinstance(rep, samara.TrainReport) and rep.method == "plain" and rep.restart_log == []
    again, rep2 = samara.train(data, method="plain", epochs=15, seed=3, min_r2=0.0)
    assert again.to_onnx() == net.to_onnx() and rep2.r2 == rep.r2  # same seed, same network
    exe = cli()
    if exe is None:
        pytest.skip("the samara CLI is not built")
    out = tmp_path / "net.onnx"
    res = subprocess.run(
        [exe, "train", "--data", str(reference("Training_Data.csv")), "--epochs", "15", "--seed", "3",
         "--min-r2", "0", "--out", str(out), "--json"],
        capture_output=True, text=True, cwd=ROOT,
    )
    assert res.returncode == 0, res.stderr
    c = json.loads(res.stdout)
    assert c["r2"] == rep.r2 and c["rmse"] == rep.rmse and c["init_seed"] == rep.init_seed
    assert out.read_bytes() == net.to_onnx()


def test_train_errors():
    with pytest.raises(ValueError, match="method"):
        samara.train(np.zeros((10, 7)), method="magic")
    with pytest.raises(ValueError):
        samara.train(np.zeros(10))


def test_reach_warns_about_a_network_in_normalised_units(ctl):
    # base_model_norm.onnx takes normalised inputs and gives a normalised output: flown
    # as a raw-unit controller its outputs lie far outside the actuator range [0.181,
    # 0.193], which `samara reach` warns about; the raw-unit file is not warned about.
    norm = samara.Network.from_onnx(reference("base_model_norm.onnx"))
    with pytest.warns(UserWarning, match="normalised units"):
        r = samara.reach(norm, y0=(2.0, 2.1), horizon=1.0)
    assert len(r.warnings) == 1 and "_denorm" in r.warnings[0]
    import warnings as w

    with w.catch_warnings():
        w.simplefilter("error")
        ok = samara.reach(ctl, y0=(2.0, 2.1), horizon=1.0)
    assert ok.warnings == [] and ok.enclosure_lost is None

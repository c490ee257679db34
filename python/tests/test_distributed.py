"""samara.distributed on a local Ray (127.0.0.1, no dashboard, 2 CPUs, shut down at the
end of the module): the P5 table with its points sharded, and a reach partition, give
results identical to one process doing the same work."""

import dataclasses
import os

import numpy as np
import pytest

ray = pytest.importorskip("ray")

import samara  # noqa: E402
import samara.distributed as sd  # noqa: E402
from conftest import reference  # noqa: E402


@pytest.fixture(scope="module")
def cluster():
    with sd.local_cluster(num_cpus=2) as r:
        assert r.is_initialized()
        yield r
    assert not ray.is_initialized()


def strip(r):
    """The result without its wall time (the only field a merge may change)."""
    return dataclasses.replace(r, seconds=0.0)


def test_shards_cover_rows():
    assert sd.shard_rows(10, 3) == [(0, 3), (3, 7), (7, 10)]
    assert sd.shard_rows(2, 5) == [(0, 1), (1, 2)]


def test_p5_table_sharded_equals_one_process(cluster):
    net = samara.Network.from_onnx(reference("base_model_norm.onnx"))
    data = samara.read_table(reference("Training_Data_Normalised.csv"))[:60]
    kw = dict(eps=[1e-3, 1e-2], lipschitz=[1e-3, 1e-2, 1e-1], max_nodes=20_000)
    one = samara.robustness(net, data, **kw)
    dist = sd.robustness(net, data, shards=5, **kw)
    assert strip(dist) == strip(one)
    assert np.array_equal(dist.success_rate, one.success_rate)
    # the merge alone (shards run here) is the same
    parts = [(s, samara.robustness(net, data[s:e], **kw)) for s, e in sd.shard_rows(60, 4)]
    assert strip(sd.merge_robustness(parts, 60)) == strip(one)


def test_reach_partition_equals_one_process(cluster):
    net = samara.Network.from_onnx(reference("base_model_denorm.onnx"))
    kw = dict(horizon=2.0, goal_ystar=5.0, max_leaves=4, samples=20)
    merged, parts = sd.reach_partition(net, y0=(2.0, 2.4), pieces=3, **kw)
    local, lparts = sd.reach_partition(net, y0=(2.0, 2.4), pieces=3, local=True, **kw)
    assert merged.verdict == "proved" == local.verdict and merged.pieces == ["proved"] * 3
    assert strip(merged) == strip(local)  # the same numbers (arrays compared element-wise)
    for k in ("t", "bbox", "x_plus_y", "x_plus_y_period", "ex"):
        assert np.array_equal(getattr(merged, k), getattr(local, k), equal_nan=True), k
    assert all(a.leaves == b.leaves for a, b in zip(parts, lparts))
    # the pieces' union encloses the whole interval's sampled flights
    whole = samara.reach(net, y0=(2.0, 2.4), **kw)
    lo, hi = whole.sampled_x_plus_y
    assert merged.final_x_plus_y[0] <= lo <= hi <= merged.final_x_plus_y[1]


def test_reach_grid_equals_one_process(cluster):
    """TORA (ARCH-COMP, the competition's controller) on a 2 x 2 grid: the cells shared
    out over Ray tasks, merged, give exactly what one process flying the grid gives, and
    the cells' hull contains the sets of the whole initial set's run."""
    from conftest import ROOT

    sys_file = ROOT / "examples" / "archcomp" / "tora.sys"
    net = samara.Network.from_onnx(ROOT / "crates" / "samara-reach" / "tests" / "data" / "archcomp" / "controller_tora.onnx")
    kw = dict(order=3, network_error="symbolic:20", samples=16)
    grid = {"x1": 2, "x3": 2}
    one = samara.reach_system(sys_file, net, grid=grid, **kw)
    assert one.verdict == "proved" and one.reason is None
    assert one.cells == (0, 4) and one.total_cells == 4 and one.covered == 1.0
    dist = sd.reach_grid(sys_file, net, grid, tasks=3, **kw)
    local = sd.reach_grid(sys_file.read_text(), net, grid, tasks=2, local=True, **kw)
    for r in (dist, local):
        assert strip(r) == strip(one)
    # the merge alone, of ranges flown here
    parts = [samara.reach_system(sys_file, net, grid=grid, cells=c, **kw) for c in [(0, 1), (1, 4)]]
    assert strip(sd.merge_reach_system(parts)) == strip(one)
    with pytest.raises(ValueError, match="do not continue"):
        sd.merge_reach_system(parts[::-1])
    # the hull rows contain every sub-box's own rows
    bbox = one.bbox
    for leaf in one.leaves:
        rows = leaf.instants
        assert np.all(bbox[: len(rows), :, 0] <= rows[..., 0])
        assert np.all(rows[..., 1] <= bbox[: len(rows), :, 1])


def _tora_widened():
    """TORA with its x1 and x3 intervals widened three times, a 3 s horizon and the band
    ``|x1 + x2| <= 100`` at the end as the measure (the CLI's adaptive tests' system)."""
    from conftest import ROOT

    text = (ROOT / "examples" / "archcomp" / "tora.sys").read_text()
    text = (text.replace("horizon 20", "horizon 3")
            .replace("init x1 in [0.6, 0.7]", "init x1 in [0.5, 0.8]")
            .replace("init x3 in [-0.4, -0.3]", "init x3 in [-0.5, -0.2]"))
    text = "".join(l + "\n" for l in text.splitlines() if not l.startswith("goal"))
    net = samara.Network.from_onnx(ROOT / "crates" / "samara-reach" / "tests" / "data" / "archcomp" / "controller_tora.onnx")
    return text + "goal band |x1 + x2| <= 100 at end\n", net


def test_reach_adaptive_on_ray_equals_one_process(cluster, tmp_path):
    """An adaptive run (target ratio 1.2 on x1 + x2, 2 x 2 starting cells) drained by Ray
    tasks on the 2-worker cluster, one task per starting cell and two tasks with
    checkpoints, merges to the reach.json of the same run in one task in this process
    (but the summed wall time); finished tasks leave no checkpoint behind."""
    text, net = _tora_widened()
    grid = {"x1": 2, "x3": 2}
    kw = dict(order=3, network_error="symbolic:20", samples=300, max_leaves=64)
    one = sd.reach_adaptive(text, net, grid, target_ratio=1.2, tasks=1, local=True, **kw)
    assert one["adaptive"]["met"] is True and one["adaptive"]["leaves"] > 4, one["adaptive"]
    assert one["settings"]["target_ratio"] == 1.2 and one["settings"]["grid"] == [2, 1, 2, 1]
    dist = sd.reach_adaptive(text, net, grid, target_ratio=1.2, **kw)
    two = sd.reach_adaptive(text, net, grid, target_ratio=1.2, tasks=2, checkpoint_dir=tmp_path, **kw)
    for r in (one, dist, two):
        r["result"].pop("seconds")
    assert dist == one
    assert two == one
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ValueError, match="grid"):
        sd.reach_adaptive(text, net, {}, target_ratio=1.2, **kw)
    with pytest.raises(TypeError, match="unknown arguments"):
        sd.reach_adaptive(text, net, grid, target_ratio=1.2, pieces=3)


def test_reach_system_bad_arguments():
    from conftest import ROOT

    sys_file = ROOT / "examples" / "archcomp" / "tora.sys"
    net = samara.Network.from_onnx(ROOT / "crates" / "samara-reach" / "tests" / "data" / "archcomp" / "controller_tora.onnx")
    with pytest.raises(ValueError, match=r"grid\["):
        samara.reach_system(sys_file, net, grid={"nope": 2})
    with pytest.raises(ValueError, match="network_error"):
        samara.reach_system(sys_file, net, network_error="symbolic:0")
    with pytest.raises(ValueError, match="cells"):
        samara.reach_system(sys_file, net, grid={"x1": 2}, cells=(1, 3))
    with pytest.raises(ValueError, match="lifted_weight"):
        samara.reach_system(sys_file, net, order=3, lifted_weight=4)
    with pytest.raises(FileNotFoundError):
        samara.reach_system("no/such.sys", net)
    glider = samara.Network.from_onnx(reference("base_model_denorm.onnx"))
    with pytest.raises(ValueError, match="observes 4 values"):
        samara.reach_system(sys_file, glider)


def test_local_cluster_binds_loopback(cluster):
    nodes = ray.nodes()
    assert nodes and all(n["NodeManagerAddress"] == "127.0.0.1" for n in nodes)
    # no listening TCP socket of this Ray on a non-loopback address
    try:
        import psutil
    except ImportError:
        return
    me = psutil.Process()
    procs = [me] + me.children(recursive=True)
    for p in procs:
        try:
            conns = p.net_connections(kind="tcp")
        except (psutil.Error, AttributeError):
            continue
        for c in conns:
            if c.status == psutil.CONN_LISTEN:
                assert c.laddr.ip in ("127.0.0.1", "::1", "::ffff:127.0.0.1"), (p.name(), c.laddr)

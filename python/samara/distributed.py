"""Scale-out on Ray: the P5 robustness table with its points sharded over tasks, a
reachability analysis with its initial height interval partitioned over tasks, a
Taylor-model run of a system file with the cells of its grid shared out over tasks, and
an adaptive run (``--target-ratio``) with the starting cells of its grid drained by
tasks (:func:`reach_adaptive`).

Each task runs the same Rust code as one process (networks travel as exact float64
ONNX bytes), and the merge is exact: the table's counts and per-point results, and the
partition's enclosures, are identical to running the same shards in one process.

Ray is optional (``pip install ray``). The functions use the Ray the caller started with
``ray.init(...)``; when none is running they start a local one with
:func:`local_cluster` settings (loopback only, no dashboard) and leave it running for
the process (call ``ray.shutdown()`` to stop it). To use a cluster::

    import ray
    ray.init(address="ray://head-node:10001")   # or address="auto" on a cluster node
    table = samara.distributed.robustness(net, data, shards=64)

Every worker needs the ``samara`` wheel installed (the same version).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import Network, ReachResult, RobustnessPoint, RobustnessResult, SystemReachResult, _samara
from . import _count, _network, _reach_system_text, _result, _system_source, _Typed
from . import reach as _reach, read_table, robustness as _robustness

__all__ = [
    "local_cluster", "robustness", "reach_partition", "reach_grid", "merge_robustness", "merge_reach",
    "merge_reach_system", "shard_rows", "MergedReach", "reach_adaptive", "merge_reach_adaptive",
]


def _loopback_only() -> None:
    """Make a Ray started here use 127.0.0.1: Ray replaces a loopback node address by
    the machine's routable one unless its cluster mode is off (its setting
    RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0, read when ray is imported; set on the loaded
    module as well if ray was imported already)."""
    os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    import sys

    rc = sys.modules.get("ray._private.ray_constants")
    if rc is not None and hasattr(rc, "ENABLE_RAY_CLUSTER"):
        rc.ENABLE_RAY_CLUSTER = False


def _ray():
    try:
        import ray  # noqa: F401
    except ImportError as e:  # pragma: no cover
        raise ImportError("samara.distributed needs Ray: pip install 'ray>=2.9'") from e
    return ray


def _local_init_args(num_cpus: Optional[int]) -> Dict[str, Any]:
    return dict(
        num_cpus=num_cpus,
        include_dashboard=False,
        _node_ip_address="127.0.0.1",
        configure_logging=False,
        log_to_driver=False,
    )


@contextlib.contextmanager
def local_cluster(num_cpus: Optional[int] = 2) -> Iterator[Any]:
    """A local Ray for the ``with`` block: bound to 127.0.0.1, no dashboard, no usage
    statistics, ``num_cpus`` workers; shut down on exit."""
    _loopback_only()
    ray = _ray()
    _loopback_only()
    ray.init(**_local_init_args(num_cpus))
    try:
        yield ray
    finally:
        ray.shutdown()


def _ensure() -> Any:
    ray = _ray()
    if not ray.is_initialized():
        _loopback_only()
        ray.init(**_local_init_args(None))
    return ray


def shard_rows(n: int, shards: int) -> List[Tuple[int, int]]:
    """`shards` contiguous [start, end) ranges covering 0..n (none empty)."""
    shards = max(1, min(int(shards), n)) if n > 0 else 1
    bounds = np.linspace(0, n, shards + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:]) if b > a] or [(0, 0)]


def merge_robustness(parts: Sequence[Tuple[int, RobustnessResult]], points: int) -> RobustnessResult:
    """Merge the tables of shards (each with its first row's index): counts add,
    success rates are recomputed over all points, per-point rows are re-indexed;
    ``seconds`` is the sum of the shards' times."""
    if not parts:
        raise ValueError("parts: give at least one (first row, RobustnessResult) pair")
    first = parts[0][1]
    counts = [[[0, 0, 0] for _ in row] for row in first.table]
    per_point: List[RobustnessPoint] = []
    seconds = 0.0
    for offset, r in parts:
        seconds += r.seconds
        for i, row in enumerate(r.table):
            for j, c in enumerate(row):
                counts[i][j][0] += c.proved
                counts[i][j][1] += c.violated
                counts[i][j][2] += c.unknown
        per_point.extend(dataclasses.replace(p, index=p.index + offset) for p in r.per_point)
    table = [
        [
            dataclasses.replace(c, proved=n[0], violated=n[1], unknown=n[2], success_rate=n[0] / max(points, 1))
            for c, n in zip(row, ns)
        ]
        for row, ns in zip(first.table, counts)
    ]
    # shards in order: per-point rows by index, then eps, as one process gives them
    return RobustnessResult(form=first.form, points=points, seconds=seconds, table=table, per_point=per_point)


def _robust_task(net: Network, rows: np.ndarray, kw: Dict[str, Any]) -> RobustnessResult:
    return _robustness(net, rows, **kw)


def robustness(
    network: Network,
    data: Any,
    eps: Sequence[float] = (1e-5, 1e-4, 1e-3, 1e-2),
    lipschitz: Sequence[float] = (1e-5, 1e-4, 1e-3, 1e-2),
    reference: str = "label",
    form: str = "published",
    timeout: float = 30.0,
    max_nodes: int = 200_000,
    shards: Optional[int] = None,
) -> RobustnessResult:
    """:func:`samara.robustness` (the P5 table) with the points in ``shards`` Ray tasks
    (default: twice the cluster's CPUs), merged with :func:`merge_robustness`."""
    ray = _ensure()
    if isinstance(data, (str, os.PathLike)):
        data = read_table(data)
    a = np.ascontiguousarray(np.asarray(data, dtype=np.float64))
    if a.ndim != 2:
        raise ValueError(f"data: shape {a.shape}, expected (rows, columns)")
    if shards is None:
        shards = 2 * int(ray.cluster_resources().get("CPU", 1))
    kw = dict(eps=list(eps), lipschitz=list(lipschitz), reference=reference, form=form,
              timeout=timeout, max_nodes=max_nodes)
    task = ray.remote(_robust_task)
    net_ref = ray.put(network)
    ranges = shard_rows(a.shape[0], shards)
    futures = [task.remote(net_ref, a[s:e], kw) for s, e in ranges]
    parts = list(zip([s for s, _ in ranges], ray.get(futures)))
    return merge_robustness(parts, a.shape[0])


def _split(lo: float, hi: float, pieces: int) -> List[Tuple[float, float]]:
    edges = [lo + (hi - lo) * i / pieces for i in range(pieces + 1)]
    edges[-1] = hi
    return list(zip(edges[:-1], edges[1:]))


@_result
class MergedReach(_Typed):
    """The reach results of a partition of the initial set, merged
    (:func:`merge_reach`): ``verdict`` ('proved' only if every piece is, 'violated' if
    any is, 'none' if no piece has a goal, else 'unknown'), ``pieces`` (the pieces'
    verdicts), the hulls over the pieces ``t`` (k,), ``bbox`` (k, 6, 2), ``x_plus_y``,
    ``x_plus_y_period`` and ``ex`` (k, 2), ``final_x_plus_y`` and ``sampled_x_plus_y``
    (2,), ``subproblems`` and ``seconds`` (sums over the pieces)."""

    verdict: str
    pieces: List[str]
    t: np.ndarray
    bbox: np.ndarray
    x_plus_y: np.ndarray
    x_plus_y_period: np.ndarray
    ex: np.ndarray
    final_x_plus_y: np.ndarray
    sampled_x_plus_y: np.ndarray
    subproblems: int
    seconds: float

    _REPR = ("verdict", "pieces", "final_x_plus_y", "subproblems")

    @property
    def proved(self) -> bool:
        return self.verdict == "proved"


def merge_reach(parts: Sequence[ReachResult]) -> MergedReach:
    """Merge the reach results of a partition of the initial set: the verdict is
    ``proved`` only if every piece is proved, ``violated`` if any is, else ``unknown``
    (``none`` without a goal); enclosures are interval hulls over the pieces."""
    if not parts:
        raise ValueError("parts: give at least one ReachResult")
    kinds = [p.verdict for p in parts]
    if all(k == "proved" for k in kinds):
        verdict = "proved"
    elif any(k == "violated" for k in kinds):
        verdict = "violated"
    elif all(k == "none" for k in kinds):
        verdict = "none"
    else:
        verdict = "unknown"

    def hull(arrs: List[np.ndarray]) -> np.ndarray:
        s = np.stack(arrs)
        return np.stack([s[..., 0].min(axis=0), s[..., 1].max(axis=0)], axis=-1)

    ex = np.stack([p.ex for p in parts])
    final = np.stack([p.final_x_plus_y for p in parts])
    return MergedReach(
        verdict=verdict,
        pieces=kinds,
        t=parts[0].t.copy(),
        bbox=hull([p.bbox for p in parts]),
        x_plus_y=hull([p.x_plus_y for p in parts]),
        x_plus_y_period=hull([p.x_plus_y_period for p in parts]),
        ex=np.stack([np.fmin.reduce(ex[..., 0], axis=0), np.fmax.reduce(ex[..., 1], axis=0)], axis=-1),
        # A NaN end (no enclosure) makes the hull's end unbounded.
        final_x_plus_y=np.array([np.nan_to_num(final[:, 0], nan=-np.inf).min(),
                                 np.nan_to_num(final[:, 1], nan=np.inf).max()]),
        sampled_x_plus_y=np.array([min(p.sampled_x_plus_y[0] for p in parts),
                                   max(p.sampled_x_plus_y[1] for p in parts)]),
        subproblems=sum(p.subproblems for p in parts),
        seconds=sum(p.seconds for p in parts),
    )


def _reach_task(net: Network, y0: Tuple[float, float], kw: Dict[str, Any]) -> ReachResult:
    return _reach(net, y0=y0, **kw)


def reach_partition(
    network: Network,
    y0: Tuple[float, float] = (0.1 / 0.07, 0.3 / 0.07),
    pieces: int = 8,
    local: bool = False,
    **kwargs: Any,
) -> Tuple[MergedReach, List[ReachResult]]:
    """:func:`samara.reach` over ``pieces`` equal parts of the height interval ``y0``, one
    Ray task each (``local=True``: in this process, one after the other — the same
    work). ``kwargs`` go to :func:`samara.reach`. Returns the merged result
    (:func:`merge_reach`) and the pieces' results."""
    ys = _split(float(y0[0]), float(y0[1]), _count("pieces", pieces, 1, 1_000_000))
    if local:
        parts = [_reach(network, y0=y, **kwargs) for y in ys]
    else:
        ray = _ensure()
        task = ray.remote(_reach_task)
        net_ref = ray.put(network)
        parts = ray.get([task.remote(net_ref, y, kwargs) for y in ys])
    return merge_reach(parts), parts


def merge_reach_system(parts: Sequence[SystemReachResult]) -> SystemReachResult:
    """Merge :func:`samara.reach_system` results of consecutive cell ranges of one grid
    (in cell order, from cell 0) into the result of their union, exactly as one process
    flying all the cells gives it (``samara_reach::grid::merge_parts``; ``seconds`` is
    the parts' sum)."""
    for i, p in enumerate(parts):
        if not isinstance(p, SystemReachResult):
            raise TypeError(f"parts[{i}]: expected samara.SystemReachResult, got {type(p).__name__}")
    return SystemReachResult._of(_samara.merge_reach_system([p._native() for p in parts]))


def _grid_task(text: str, name: str, net: Network, grid: Dict[str, int], cells: Tuple[int, int],
               kw: Dict[str, Any]) -> SystemReachResult:
    return _reach_system_text(text, name, net, grid, cells, **kw)


def reach_grid(
    system: Any,
    network: Network,
    grid: Dict[str, int],
    tasks: Optional[int] = None,
    local: bool = False,
    **kwargs: Any,
) -> SystemReachResult:
    """:func:`samara.reach_system` with ``grid``, its cells shared out in ``tasks``
    contiguous ranges (default: twice the cluster's CPUs), one Ray task each
    (``local=True``: in this process, one after the other), merged with
    :func:`merge_reach_system`: the same result as ``reach_system(..., grid=grid)``
    (but ``seconds``, the tasks' sum). ``kwargs`` go to :func:`samara.reach_system`
    (each task gets the whole ``timeout``)."""
    text, name = _system_source(system)
    # The number of cells, the product of the pieces (the first task checks them).
    total = 1
    for v in grid.values():
        total *= max(int(v), 1)
    if local:
        ranges = shard_rows(total, tasks or 1)
        parts = [_grid_task(text, name, network, dict(grid), r, kwargs) for r in ranges]
    else:
        ray = _ensure()
        ranges = shard_rows(total, tasks or 2 * int(ray.cluster_resources().get("CPU", 1)))
        task = ray.remote(_grid_task)
        net_ref = ray.put(network)
        parts = ray.get([task.remote(text, name, net_ref, dict(grid), r, kwargs) for r in ranges])
    return merge_reach_system(parts)


def _adaptive_task(text: str, name: str, net: Network, grid: Dict[str, int], shard: Tuple[int, int],
                   target_ratio: float, kw: Dict[str, Any], checkpoint: Optional[str]) -> str:
    return _samara.reach_adaptive_shard(
        text, name, _network("network", net), {str(k): int(v) for k, v in grid.items()}, shard, float(target_ratio),
        int(kw.get("order", 4)), str(kw.get("network_error", "auto")), int(kw.get("lifted_weight", 1)),
        float(kw.get("lift_at", 0.05)), int(kw.get("max_leaves", 256)), int(kw.get("samples", 200)),
        int(kw.get("seed", 1)), None if kw.get("timeout") is None else float(kw["timeout"]), checkpoint,
        None if kw.get("time_order") is None else int(kw["time_order"]),
        None if kw.get("step_tol") is None else float(kw["step_tol"]),
    )


_ADAPTIVE_KW = {"order", "network_error", "lifted_weight", "lift_at", "max_leaves", "samples", "seed", "timeout",
                "time_order", "step_tol"}


def merge_reach_adaptive(docs: Sequence[str]) -> Dict[str, Any]:
    """Join the shard documents of one adaptive run (every shard ``(i, n)`` once, any
    order) into ``reach.json`` of the one-process run, as a dict
    (``samara_app::reach::adaptive::merge_documents``). Refused (``ValueError``) where
    the merge would not be the one-process result: a shard stopped early by its timeout
    or budget, or the shards' cells together past ``max_leaves``."""
    return json.loads(_samara.merge_adaptive_shards([str(d) for d in docs]))


def reach_adaptive(
    system: Any,
    network: Network,
    grid: Dict[str, int],
    target_ratio: float = 2.0,
    tasks: Optional[int] = None,
    checkpoint_dir: Optional[Union[str, os.PathLike]] = None,
    local: bool = False,
    **kwargs: Any,
) -> Dict[str, Any]:
    """``samara reach --system FILE --target-ratio R --grid ...`` with the grid's starting
    cells drained by ``tasks`` Ray tasks (default: one per starting cell, so Ray's queue
    hands them to whichever worker is free; task ``i`` of ``n`` flies the starting cells
    ``i`` mod ``n``, as ``--shard i/n``), merged with :func:`merge_reach_adaptive`: the
    ``reach.json`` one process writes, as a dict (but ``result.seconds``, the tasks'
    sum). ``local=True``: the tasks in this process, one after the other.

    ``checkpoint_dir`` (a folder every worker can write, e.g. on a shared file system):
    task ``i`` keeps its finished starting cells in ``shard-i-of-n.cells`` there, so a
    task Ray runs again after its worker died skips them (Ray retries a task whose
    worker died, 3 times by default). ``kwargs``: ``order``, ``network_error``,
    ``lifted_weight``, ``lift_at``, ``max_leaves`` (per task, and for the whole run: a
    merge past it is refused), ``samples``, ``seed``, ``timeout`` (per task),
    ``time_order`` and ``step_tol`` (the flow's ``--time-order`` and ``--step-tol``)."""
    bad = set(kwargs) - _ADAPTIVE_KW
    if bad:
        raise TypeError(f"reach_adaptive: unknown arguments {sorted(bad)}; give {sorted(_ADAPTIVE_KW)}")
    if not grid:
        raise ValueError("grid: an adaptive run is sharded by the starting cells of a grid; give grid={state: pieces}")
    text, name = _system_source(system)
    total = 1
    for v in grid.values():
        total *= max(int(v), 1)
    n = _count("tasks", tasks if tasks is not None else total, 1, total)
    cps: List[Optional[str]] = [None] * n
    if checkpoint_dir is not None:
        os.makedirs(checkpoint_dir, exist_ok=True)
        cps = [os.path.join(os.fspath(checkpoint_dir), f"shard-{i}-of-{n}.cells") for i in range(n)]
    args = [(text, name, dict(grid), (i, n), target_ratio, dict(kwargs), cps[i]) for i in range(n)]
    if local:
        docs = [_adaptive_task(a[0], a[1], network, *a[2:]) for a in args]
    else:
        ray = _ensure()
        task = ray.remote(_adaptive_task)
        net_ref = ray.put(network)
        docs = ray.get([task.remote(a[0], a[1], net_ref, *a[2:]) for a in args])
    return merge_reach_adaptive(docs)

"""samara for Python: networks, specifications and exact verification of the
Alsomitra glider's neural-network controllers.

The computations run in Rust (the same library code as the ``samara`` CLI) and release
the GIL. Arrays are numpy float64; networks and specs need no files (ONNX bytes and
spec text are accepted as well as paths).

Errors: bad arguments raise ``ValueError`` (with the library's message), a missing file
``FileNotFoundError``, a failed computation ``samara.SamaraError``.
"""

from __future__ import annotations

import math
import os
import re
import tempfile
import warnings
import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union


import numpy as np

from . import _samara
from ._samara import SamaraError

__version__ = _samara.__version__

__all__ = [
    "SystemReachResult",
    "reach_system",
    "Network",
    "Spec",
    "VerifyResult",
    "CriticalResult",
    "RobustnessResult",
    "robustness",
    "read_table",
    "simulate",
    "reach",
    "ReachResult",
    "STATE_NAMES",
    "train",
    "SamaraError",
]

PathLike = Union[str, "os.PathLike[str]"]


def _count(name: str, v: Any, lo: int = 0, hi: int = 2**63 - 1) -> int:
    """An integer argument, checked here so that the error names it: TypeError for a
    non-integer, OverflowError outside [lo, hi] (as Python's own conversions)."""
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
        raise TypeError(f"{name}={v!r}: expected an integer, got {type(v).__name__}")
    v = int(v)
    if not lo <= v <= hi:
        raise OverflowError(f"{name}={v}: out of range; give an integer in [{lo}, {hi}]")
    return v


def _timeout(v: Any) -> float:
    """A time limit in seconds (``math.inf``: none), named in its error."""
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise TypeError(f"timeout={v!r}: expected a number of seconds, got {type(v).__name__}")
    return float(v)


def _str(name: str, v: Any) -> str:
    if not isinstance(v, str):
        raise TypeError(f"{name}={v!r}: expected a str, got {type(v).__name__}")
    return v


def _rows(x: Any, width: int, what: str) -> Tuple[np.ndarray, bool]:
    """`x` as a C-contiguous float64 matrix of `width` columns; whether it was one row."""
    a = np.asarray(x, dtype=np.float64)
    if a.ndim == 1:
        if a.shape[0] != width:
            raise ValueError(f"{what}: {a.shape[0]} values, expected {width}")
        return np.ascontiguousarray(a.reshape(1, width)), True
    if a.ndim != 2 or a.shape[1] != width:
        raise ValueError(
            f"{what}: shape {a.shape}, expected (n, {width}) (one row per point) or ({width},)"
        )
    return np.ascontiguousarray(a), False


class Network:
    """A feed-forward network (dense layers and activations, optional input
    normalisation and output denormalisation), evaluated in float64.

    Build one with :meth:`from_onnx` (a path or the bytes of an ONNX file), from a
    PyTorch module with :meth:`from_torch`, or from :func:`train`.
    """

    __slots__ = ("_net", "_source")

    def __init__(self, _net: "_samara.Network", _source: str = "<memory>"):
        self._net = _net
        # Where it came from (a path, "<bytes>", "<torch ...>"): ReachResult.settings.
        self._source = _source

    @staticmethod
    def from_onnx(path_or_bytes: Union[PathLike, bytes, bytearray, memoryview]) -> "Network":
        """Import an ONNX network from a file path or from its bytes.

        Raises FileNotFoundError for a missing file, ValueError for a file samara
        cannot import (the message names the operator or the problem)."""
        if isinstance(path_or_bytes, (bytes, bytearray, memoryview)):
            return Network(_samara.Network.from_onnx_bytes(bytes(path_or_bytes), "<bytes>"), "<bytes>")
        p = os.fspath(path_or_bytes)
        with open(p, "rb") as f:
            data = f.read()
        return Network(_samara.Network.from_onnx_bytes(data, p), p)

    @staticmethod
    def from_torch(module: Any, n_inputs: Optional[int] = None) -> "Network":
        """Import a PyTorch module (an ``nn.Sequential`` of ``Linear`` layers and
        ReLU/Tanh/Sigmoid activations, or any module ``torch.onnx`` exports to those)
        through an in-memory ``torch.onnx.export`` (opset 13, TorchScript exporter): no
        file is written. ``n_inputs`` defaults to the first ``Linear``'s
        ``in_features``. The weights are read in the module's dtype (float32 unless it
        was converted) and evaluated in float64 from then on.

        torch is an optional dependency: ImportError (with the install line) when it is
        missing; ValueError when the export holds an operator samara cannot import."""
        try:
            import torch
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError(
                "Network.from_torch needs PyTorch: pip install torch "
                "(CPU wheels: --index-url https://download.pytorch.org/whl/cpu)"
            ) from e
        import inspect
        import io

        if not isinstance(module, torch.nn.Module):
            raise ValueError(f"Network.from_torch: expected a torch.nn.Module, got {type(module).__name__}")
        params = list(module.parameters())
        dtype = params[0].dtype if params else torch.float32
        if n_inputs is None:
            first = next((m for m in module.modules() if isinstance(m, torch.nn.Linear)), None)
            if first is None:
                raise ValueError(
                    "Network.from_torch: the module has no nn.Linear layer; pass n_inputs="
                )
            n_inputs = first.in_features
        was_training = module.training
        module.eval()
        buf = io.BytesIO()
        kw: Dict[str, Any] = dict(
            input_names=["input"], output_names=["output"], opset_version=13,
            dynamic_axes={"input": {0: "batch"}, "output": {0: "batch"}},
        )
        if "dynamo" in inspect.signature(torch.onnx.export).parameters:
            kw["dynamo"] = False  # the TorchScript exporter: plain Gemm/MatMul graphs
        try:
            # torch >= 2.9 marks the TorchScript exporter deprecated; it is still the one
            # that needs nothing beyond torch (the dynamo exporter needs onnxscript).
            with torch.no_grad(), warnings.catch_warnings():
                warnings.simplefilter("ignore", DeprecationWarning)
                torch.onnx.export(module, (torch.zeros(1, int(n_inputs), dtype=dtype),), buf, **kw)
        finally:
            module.train(was_training)
        src = f"<torch {type(module).__name__}>"
        return Network(_samara.Network.from_onnx_bytes(buf.getvalue(), src), src)

    def to_onnx(self, with_normalisation: bool = True, float64: bool = False) -> bytes:
        """The network as ONNX bytes (opset 13). ``with_normalisation=False`` gives the
        body only (normalised units); ``float64=True`` keeps every weight exactly
        (float32 tensors otherwise, as the published files)."""
        return self._net.to_onnx(with_normalisation, float64)

    @property
    def n_inputs(self) -> int:
        """Number of inputs."""
        return self._net.n_inputs

    @property
    def n_outputs(self) -> int:
        """Number of outputs."""
        return self._net.n_outputs

    @property
    def input_names(self) -> List[str]:
        return list(self._net.input_names)

    @property
    def output_names(self) -> List[str]:
        return list(self._net.output_names)

    def eval(self, x: Any) -> np.ndarray:
        """Evaluate in float64: ``x`` of shape (n, n_inputs) gives (n, n_outputs); a single
        point of shape (n_inputs,) gives (n_outputs,). A NaN, infinite or ``None``
        input raises ``ValueError`` naming its index: the network has no value there
        (a NaN would otherwise vanish inside a ReLU and come out as a number)."""
        a, single = _rows(x, self.n_inputs, "Network.eval")
        n = a.shape[0]
        y = np.frombuffer(self._net.eval_rows(a.tobytes(), n), dtype=np.float64)
        y = y.reshape(n, self.n_outputs)
        return y[0].copy() if single else y.copy()

    __call__ = eval

    def __repr__(self) -> str:
        return f"Network(n_inputs={self.n_inputs}, n_outputs={self.n_outputs})"

    def __reduce__(self):  # picklable (Ray ships networks to workers as ONNX bytes)
        return (_network_from_bytes, (self.to_onnx(True, True), self._source))


def _network_from_bytes(b: bytes, source: str = "<bytes>") -> Network:
    n = Network.from_onnx(b)
    n._source = source
    return n


class _Result:
    """Fields of the CLI's ``--json`` output as attributes; ``as_dict()`` gives them all."""

    def __init__(self, d: Dict[str, Any]):
        self.__dict__["_d"] = d

    def as_dict(self) -> Dict[str, Any]:
        return dict(self._d)

    def __getattr__(self, k: str) -> Any:
        try:
            return self.__dict__["_d"][k]
        except KeyError:
            raise AttributeError(k) from None

    def __getitem__(self, k: str) -> Any:
        return self._d[k]

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _Result) and type(other) is type(self) and other._d == self._d

    def __repr__(self) -> str:
        # One short line: the verdict and the scalar fields (the full data: as_dict()).
        parts = []
        for k, v in self._d.items():
            if k == "verdict" and isinstance(v, dict):
                v = v.get("verdict")
            if v is None or isinstance(v, (str, bool, int, float)):
                r = repr(v)
                if len(r) <= 40:
                    parts.append(f"{k}={r}")
            if len(parts) == 6:
                break
        return f"{type(self).__name__}({', '.join(parts)}, ...)"

    def __dir__(self) -> List[str]:
        return sorted(set(super().__dir__()) | set(self._d))

    def __setattr__(self, k: str, v: Any) -> None:
        raise AttributeError(
            f"{type(self).__name__} is read-only: its fields are results (copy as_dict() to change them)"
        )

    def __delattr__(self, k: str) -> None:
        raise AttributeError(f"{type(self).__name__} is read-only")

    def __reduce__(self):
        return (type(self), (self._d,))


class _Typed:
    """Base of the typed results (frozen dataclasses built from the library's typed
    values): fields are attributes (in ``dir()``, not assignable), ``as_dict()`` gives
    them all as plain data, ``r["field"]`` reads one, and ``repr`` is one short line."""

    _REPR: Tuple[str, ...] = ()

    def as_dict(self) -> Dict[str, Any]:
        return dataclasses.asdict(self)

    def __getitem__(self, k: str) -> Any:
        if k not in {f.name for f in dataclasses.fields(self)}:
            raise KeyError(k)
        return getattr(self, k)

    def __repr__(self) -> str:
        parts = ", ".join(f"{k}={getattr(self, k)!r}" for k in self._REPR)
        return f"{type(self).__name__}({parts})"


@dataclasses.dataclass(frozen=True, repr=False, eq=True)
class VerifyResult(_Typed):
    """One property instance of :meth:`Spec.verify` (the library's verdict row, the
    fields of ``samara verify --json``): ``property``, ``verdict`` ('proved' |
    'violated' | 'unknown'), ``counterexample`` (``{'point': [{'network', 'values':
    {name: value}}], 'margin', 'exact_check'}``, ``{'reason'}`` when unknown, or None),
    ``seconds``, ``vacuous``, ``vacuity``, ``unknown_reason`` (``{'kind', 'message'}``
    or None). ``witness`` is the counterexample's values as one dict."""

    property: str
    verdict: str
    counterexample: Optional[Dict[str, Any]]
    seconds: float
    vacuous: bool
    vacuity: Optional[str]
    unknown_reason: Optional[Dict[str, str]]

    _REPR = ("property", "verdict", "seconds")

    @property
    def witness(self) -> Optional[Dict[str, float]]:
        cx = self.counterexample
        if not cx or "point" not in cx:
            return None
        return _flat_point(cx["point"])


@dataclasses.dataclass(frozen=True, repr=False, eq=True)
class CriticalResult(_Typed):
    """The result of :meth:`Spec.critical` (the library's critical value, the fields of
    ``samara critical --json``): ``property``, ``parameter``, ``holds`` ('above' |
    'below' | 'everywhere' | 'nowhere' | 'unknown'), ``critical``, ``bound``,
    ``threshold``, ``attained``, ``vacuous``, ``domain_extreme``,
    ``counterexample_range`` (inf, sup), ``witness`` (as the CLI: a list of
    ``{'network', 'values'}``), ``complete``, ``unknown_reason``, ``seconds``.
    ``witness_values`` is the witness as one dict."""

    property: str
    parameter: str
    holds: str
    critical: Optional[float]
    bound: Optional[float]
    threshold: Optional[float]
    attained: bool
    vacuous: bool
    domain_extreme: Optional[float]
    counterexample_range: Tuple[Optional[float], Optional[float]]
    witness: Optional[List[Dict[str, Any]]]
    complete: bool
    unknown_reason: Optional[Dict[str, str]]
    seconds: float

    _REPR = ("property", "parameter", "holds", "critical", "threshold")

    @property
    def witness_values(self) -> Optional[Dict[str, float]]:
        return None if self.witness is None else _flat_point(self.witness)


@dataclasses.dataclass(frozen=True, repr=False, eq=True)
class RobustnessResult(_Typed):
    """The result of :func:`robustness` (the library's robustness table, the fields of
    ``samara robustness --json``): ``form``, ``points``, ``seconds``, ``table`` (rows
    eps, columns L: ``{'eps', 'L', 'proved', 'violated', 'unknown', 'success_rate'}``),
    plus ``per_point`` (the CSV of ``--out`` as dicts, rows counted from 0).
    ``success_rate`` is the table as a numpy array."""

    form: str
    points: int
    seconds: float
    table: List[List[Dict[str, Any]]]
    per_point: List[Dict[str, Any]]

    _REPR = ("form", "points", "seconds")

    @property
    def success_rate(self) -> np.ndarray:
        return np.array([[c["success_rate"] for c in row] for row in self.table])


def _flat_point(apps: List[Dict[str, Any]]) -> Dict[str, float]:
    out: Dict[str, float] = {}
    multi = len(apps) > 1
    for i, a in enumerate(apps):
        for k, v in a["values"].items():
            out[f"{a['network']}[{i}].{k}" if multi else k] = v
    return out


class _Datasets:
    """Data-set bindings as file paths; numpy arrays are written to temporary CSV files
    (the library binds data sets by path), removed on exit."""

    def __init__(self, datasets: Optional[Mapping[str, Any]]):
        self.paths: Dict[str, str] = {}
        self._tmp: List[str] = []
        for k, v in (datasets or {}).items():
            if isinstance(v, (str, os.PathLike)):
                p = os.fspath(v)
                if not os.path.isfile(p):
                    raise FileNotFoundError(f"datasets[{k!r}]: no such file: {p}")
                self.paths[k] = p
            else:
                a = np.asarray(v, dtype=np.float64)
                if a.ndim != 2:
                    raise ValueError(f"datasets[{k!r}]: shape {a.shape}, expected (rows, columns)")
                fd, p = tempfile.mkstemp(prefix=f"samara-{k}-", suffix=".csv")
                with os.fdopen(fd, "w") as f:
                    np.savetxt(f, a, delimiter=",", fmt="%.17g")
                self._tmp.append(p)
                self.paths[k] = p

    def __enter__(self) -> Dict[str, str]:
        return self.paths

    def _words(self, msg: str) -> str:
        """A message in the caller's words: a temporary file is the array it holds
        (``datasets['d']``), and its line N (no header) is the array's row N - 1."""
        for k, p in self.paths.items():
            if p not in self._tmp:
                continue
            name = f"datasets[{k!r}]"

            def row(m: "re.Match[str]") -> str:
                return f"{name} row {int(m.group(1)) - 1}"

            # `FILE:N` and `FILE: line N` (1-based lines of a file without header).
            msg = re.sub(re.escape(p) + r"(?::| at)? ?(?:line )?(\d+)\b", row, msg)
            msg = msg.replace(p, name)
        return msg

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        for p in self._tmp:
            try:
                os.remove(p)
            except OSError:
                pass
        if exc is not None and self._tmp:
            text = str(exc)
            words = self._words(text)
            if words != text and isinstance(exc, (ValueError, SamaraError)):
                raise type(exc)(words) from None


def _nets(networks: Optional[Mapping[str, Network]]) -> Dict[str, "_samara.Network"]:
    out = {}
    for k, v in (networks or {}).items():
        if not isinstance(v, Network):
            raise TypeError(f"networks[{k!r}]: expected samara.Network, got {type(v).__name__}")
        out[k] = v._net
    return out


def _params(params: Optional[Mapping[str, float]]) -> Dict[str, float]:
    out = {}
    for k, v in (params or {}).items():
        try:
            out[k] = float(v)
        except (TypeError, ValueError):
            raise ValueError(f"params[{k!r}] = {v!r}: not a number") from None
    return out


def _warn(ws: Iterable[str]) -> None:
    for w in ws:
        warnings.warn(w, stacklevel=3)


# The words a line of spec text starts with (a one-line string starting otherwise is
# a path, so a missing file is FileNotFoundError, not a parse error of its name).
_SPEC_STARTS = [[w] for w in ("network", "normalise", "normalize", "param", "dataset", "domain", "property", "loop", "#")]


class Spec:
    """A specification in samara's property language, from text or a file path.

    ``Spec("models/alsomitra/alsomitra.spec")`` reads a file (relative data-set paths
    are resolved against its folder); ``Spec("network f(x) -> (y) ...")`` parses text
    (relative paths against ``dir``, default the current folder). Raises ValueError with
    the parser's message (file:line:column, the line, a hint) for bad text and
    FileNotFoundError for a missing file.
    """

    def __init__(self, text_or_path: PathLike, dir: Optional[PathLike] = None):
        if not isinstance(text_or_path, (str, os.PathLike)):
            raise TypeError(
                f"text_or_path={text_or_path!r}: expected spec text or a path, got {type(text_or_path).__name__}"
            )
        if isinstance(text_or_path, os.PathLike) or (
            "\n" not in text_or_path
            and (
                text_or_path.endswith(".spec")
                or os.path.isfile(text_or_path)
                or text_or_path.split(None, 1)[:1] not in _SPEC_STARTS
            )
        ):
            p = Path(os.fspath(text_or_path))
            with open(p, "rb") as f:
                raw = f.read()
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError as e:
                raise ValueError(f"{p}: not UTF-8 text: {e}") from None
            self._spec = _samara.Spec(text, str(p), str(p.parent))
        else:
            d = os.fspath(dir) if dir is not None else "."
            self._spec = _samara.Spec(str(text_or_path), "<string>", d)

    @property
    def properties(self) -> List[str]:
        """Property names in order."""
        return list(self._spec.properties)

    @property
    def networks(self) -> Dict[str, Tuple[List[str], List[str]]]:
        """Declared networks: name -> (input names, output names)."""
        return {n: (list(i), list(o)) for n, i, o in self._spec.networks}

    @property
    def params(self) -> Dict[str, Optional[Tuple[float, float]]]:
        """Declared parameters: name -> range (or None)."""
        return dict(self._spec.params)

    def verify(
        self,
        networks: Mapping[str, Network],
        params: Optional[Mapping[str, float]] = None,
        datasets: Optional[Mapping[str, Any]] = None,
        property: Optional[str] = None,
        timeout: float = 60.0,
        max_nodes: int = 200_000,
        lp_tighten: bool = False,
    ) -> List[VerifyResult]:
        """Verify every property (or only ``property``): one :class:`VerifyResult` per
        instance (a data-set property has one per point), as ``samara verify --json``.

        ``datasets`` maps a data-set name to a CSV/IDX path or a numpy array (inputs,
        then the label). ``timeout`` is per query in seconds (``math.inf``: none)."""
        with _Datasets(datasets) as ds:
            rows, ws = self._spec.verify(
                _nets(networks), _params(params), ds, property, _timeout(timeout), _count("max_nodes", max_nodes), bool(lp_tighten)
            )
        _warn(ws)
        return [VerifyResult(**d) for d in rows]

    def critical(
        self,
        property: str,
        param: str,
        networks: Mapping[str, Network],
        params: Optional[Mapping[str, float]] = None,
        datasets: Optional[Mapping[str, Any]] = None,
        timeout: float = 60.0,
        max_nodes: int = 200_000,
        lp_tighten: bool = False,
    ) -> CriticalResult:
        """The critical value of parameter ``param`` (declared with a range) for
        ``property``, as ``samara critical --json``."""
        with _Datasets(datasets) as ds:
            d, ws = self._spec.critical(
                _str("property", property), _str("param", param), _nets(networks), _params(params), ds,
                _timeout(timeout), _count("max_nodes", max_nodes), bool(lp_tighten)
            )
        _warn(ws)
        return CriticalResult(**d)

    def __repr__(self) -> str:
        return f"Spec({self._spec.file!r}, properties={self.properties})"


def read_table(path: PathLike) -> np.ndarray:
    """A CSV (optional header) or IDX table as samara reads it: float64 (rows, columns)."""
    b, n, c = _samara.read_table(os.fspath(path))
    return np.frombuffer(b, dtype=np.float64).reshape(n, c).copy()


def robustness(
    network: Network,
    data: Any,
    eps: Sequence[float] = (1e-5, 1e-4, 1e-3, 1e-2),
    lipschitz: Sequence[float] = (1e-5, 1e-4, 1e-3, 1e-2),
    reference: str = "label",
    form: str = "published",
    timeout: float = 30.0,
    max_nodes: int = 200_000,
) -> RobustnessResult:
    """The robustness table of ``samara robustness``: for each radius in ``eps`` and bound
    in ``lipschitz``, how many points of ``data`` (array of rows: the network's inputs,
    then the label; or a CSV/IDX path) are proved, violated or unknown."""
    if isinstance(data, (str, os.PathLike)):
        data = read_table(data)
    a = np.asarray(data, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError(f"data: shape {a.shape}, expected (rows, columns)")
    a = np.ascontiguousarray(a)
    d = _samara.robustness(
        network._net,
        a.tobytes(),
        a.shape[0],
        a.shape[1],
        [float(e) for e in eps],
        [float(v) for v in lipschitz],
        reference,
        form,
        _timeout(timeout),
        _count("max_nodes", max_nodes),
    )
    return RobustnessResult(**d)


STATE_NAMES = ["v_xp", "v_yp", "omega", "theta", "x", "y", "E"]


def simulate(
    model: str = "plate6",
    controller: Union[str, float, Network] = "pid",
    y0: Optional[Sequence[float]] = None,
    integrator: str = "ode45",
    horizon: float = 20.0,
    period: float = 0.5,
    clip: bool = True,
) -> List[Dict[str, Any]]:
    """Closed-loop flights as ``samara simulate`` flies them (no files written).

    ``controller``: ``"pid"``, a number (a constant ex in [0.181, 0.193]) or a
    :class:`Network` (6 raw inputs, 1 raw output; clipped to [0.181, 0.193] unless
    ``clip=False``). ``y0``: initial heights (default: the nine published starts).

    One dict per start: ``y0``, ``t`` (n,), ``states`` (n, dim) with columns
    ``state_names``, ``ex`` (n,) (the control held from each row on), ``initial``,
    ``final_state`` and ``rhs_evals``."""
    net = None
    ex = 0.0
    if isinstance(controller, Network):
        kind, net = "network", controller._net
    elif isinstance(controller, str) and controller.startswith("constant:"):
        kind, ex = "constant", float(controller.split(":", 1)[1])
    elif isinstance(controller, (int, float)) and not isinstance(controller, bool):
        kind, ex = "constant", float(controller)
    else:
        kind = str(controller)
    starts = None if y0 is None else [float(v) for v in np.atleast_1d(np.asarray(y0, dtype=np.float64))]
    flights = _samara.simulate(
        model, kind, ex, net, bool(clip), starts, integrator, float(horizon), float(period)
    )
    out = []
    for data, width, initial, evals in flights:
        a = np.frombuffer(data, dtype=np.float64).reshape(-1, width)
        dim = width - 2
        out.append(
            {
                "y0": initial[5],
                "t": a[:, 0].copy(),
                "ex": a[:, 1].copy(),
                "states": a[:, 2:].copy(),
                "state_names": STATE_NAMES[:dim],
                "initial": np.array(initial),
                "final_state": dict(zip(STATE_NAMES[:dim], a[-1, 2:].tolist())),
                "rhs_evals": evals,
            }
        )
    return out


def _interval(name: str, v: Any) -> Tuple[float, float]:
    """An interval given as (lo, hi) or one value; anything longer is refused (a
    three-value tuple is not an interval)."""
    a = np.atleast_1d(np.asarray(v, dtype=np.float64))
    if a.ndim != 1 or len(a) not in (1, 2):
        raise ValueError(f"{name}={v!r}: give an interval as (lo, hi) or a single value, not {a.size} values")
    return (float(a[0]), float(a[-1]))


def _iv(v: Any) -> List[float]:
    return [math.nan if x is None else x for x in v]


class ReachResult(_Result):
    """The result of :func:`reach` (the fields of ``samara reach``'s ``reach.json``:
    ``settings``, ``verdict`` (``{'verdict': 'proved' | 'violated' | 'unknown' | 'none',
    'reason'?, 'counterexample'?}``), ``final_x_plus_y``, ``sampled_x_plus_y``,
    ``width_ratio``, ``subproblems``, ``seconds``, ``sampled_trajectories``,
    ``state_names``, ``leaves``, ``warnings`` (a network in the wrong units) and
    ``enclosure_lost`` (``None``, or where the sets stopped before the horizon, which
    ``samara reach`` reports with exit code 1)), plus arrays per control instant:

    - ``t``: (k,) the control instants;
    - ``bbox``: (k, 6, 2) the interval hull over all sub-boxes of the six physical states;
    - ``x_plus_y``: (k, 2) the enclosure of x + y at each instant; ``x_plus_y_period``:
      over the period ending there;
    - ``ex``: (k, 2) the control held from each instant (NaN at the horizon).

    Where a sub-box stopped early (``leaves[i]['failure']``) the later instants are
    unbounded (-inf, inf)."""

    def __init__(self, d: Dict[str, Any]):
        super().__init__(d)
        leaves = d["leaves"]
        k = int(round(d["settings"]["horizon"] / d["settings"]["period"])) + 1
        nb = 6
        bbox = np.empty((k, nb, 2))
        bbox[..., 0], bbox[..., 1] = np.inf, -np.inf
        xy = np.tile([np.inf, -np.inf], (k, 1))
        xyp = np.tile([np.inf, -np.inf], (k, 1))
        ex = np.tile([np.inf, -np.inf], (k, 1))
        t = np.array([i * d["settings"]["period"] for i in range(k)])
        for leaf in leaves:
            steps = leaf["steps"]
            for i in range(k):
                if i < len(steps):
                    st = steps[i]
                    b = np.array([_iv(iv) for iv in st["bbox"]])[:nb]
                    lo, hi = np.nan_to_num(b[:, 0], nan=-np.inf), np.nan_to_num(b[:, 1], nan=np.inf)
                    bbox[i, :, 0] = np.minimum(bbox[i, :, 0], lo)
                    bbox[i, :, 1] = np.maximum(bbox[i, :, 1], hi)
                    t[i] = st["t"]
                    for arr, key in ((xy, "x_plus_y"), (xyp, "x_plus_y_period"), (ex, "ex")):
                        v = st.get(key)
                        if v is None:
                            continue
                        lo_, hi_ = _iv(v)
                        arr[i, 0] = min(arr[i, 0], -np.inf if math.isnan(lo_) else lo_)
                        arr[i, 1] = max(arr[i, 1], np.inf if math.isnan(hi_) else hi_)
                else:
                    bbox[i, :, 0], bbox[i, :, 1] = -np.inf, np.inf
                    xy[i], xyp[i] = (-np.inf, np.inf), (-np.inf, np.inf)
        ex[np.isinf(ex[:, 0]) & (ex[:, 0] > 0)] = np.nan
        self.__dict__["t"] = t
        self.__dict__["bbox"] = bbox
        self.__dict__["x_plus_y"] = xy
        self.__dict__["x_plus_y_period"] = xyp
        self.__dict__["ex"] = ex

    @property
    def proved(self) -> bool:
        return self._d["verdict"]["verdict"] == "proved"


def reach(
    network: Network,
    model: str = "reduced",
    y0: Tuple[float, float] = (0.1 / 0.07, 0.3 / 0.07),
    init: Optional[Mapping[str, Union[float, Tuple[float, float]]]] = None,
    horizon: float = 20.0,
    period: float = 0.5,
    goal_ystar: Optional[float] = None,
    goal_from: Optional[float] = None,
    clip: bool = True,
    max_leaves: Optional[int] = None,
    samples: Optional[int] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
) -> ReachResult:
    """Sound reachable sets of the closed loop as ``samara reach`` computes them (no
    files written): the initial set is (1, 0, 0, 0, 0, y0[, 0]) with ``y0`` an interval
    (default the published [1.4286, 4.2857]) and ``init`` overriding other states
    (``{'theta': (-0.01, 0.01)}``). ``goal_ystar``: the goal |x + y| <= Y at the horizon
    (or on [goal_from, horizon]). ``threads``: worker threads (default all cores), as
    ``samara reach --threads``; ``r.settings`` names it and the network's source."""
    if not isinstance(network, Network):
        raise TypeError(f"network={network!r}: expected samara.Network (samara.Network.from_onnx(path))")
    iv: Dict[str, Tuple[float, float]] = {"y": _interval("y0", y0)}
    for k, v in (init or {}).items():
        if k == "y":
            raise ValueError("init['y']: give the height interval as y0")
        iv[k] = _interval(f"init[{k!r}]", v)
    d = _samara.reach(
        network._net, model, iv, float(horizon), float(period),
        None if goal_ystar is None else float(goal_ystar),
        None if goal_from is None else float(goal_from),
        bool(clip),
        None if max_leaves is None else _count("max_leaves", max_leaves),
        None if samples is None else _count("samples", samples),
        None if seed is None else _count("seed", seed, 0, 2**64 - 1),
        network._source,
        None if threads is None else _count("threads", threads, 1, 1024),
    )
    r = ReachResult(d)
    # What `samara reach` prints on stderr: a network in the wrong units, an enclosure
    # lost before the horizon (then ``r['enclosure_lost']`` says where).
    for w in r["warnings"]:
        warnings.warn(w, stacklevel=2)
    if r["enclosure_lost"]:
        warnings.warn(r["enclosure_lost"], stacklevel=2)
    return r


class SystemReachResult(_Result):
    """The result of :func:`reach_system` (the ``result`` of ``samara reach --system``'s
    ``reach.json``: ``system``, ``verdict`` (``{'verdict': 'proved' | 'violated' |
    'unknown' | 'none', ...}``), ``instants`` and ``periods`` (per control instant /
    period, the hull over the sub-boxes of every state as ``[lo, hi]``), ``boxes``,
    ``covered``, ``order``, ``network_error``, ``seconds``, ``leaves``, ``measures``),
    plus ``cells`` (``[start, end]`` of a grid run, else None) and ``total_cells``.
    ``bbox`` is ``instants`` as a numpy array (k, states, 2)."""

    @property
    def bbox(self) -> np.ndarray:
        return np.asarray(self._d["instants"], dtype=np.float64).reshape(len(self._d["instants"]), -1, 2)


def _system_result(d: Dict[str, Any]) -> SystemReachResult:
    r = dict(d["reach"])
    r["cells"] = d["cells"]
    r["total_cells"] = d["total_cells"]
    return SystemReachResult(r)


def _system_source(system: Union[str, PathLike]) -> Tuple[str, str]:
    """A system given as a path or as the file's text: (text, name for messages)."""
    if isinstance(system, os.PathLike) or (isinstance(system, str) and "\n" not in system):
        p = Path(system)
        if not p.is_file():
            raise FileNotFoundError(f"system {str(system)!r}: no such file; pass a system file's path or its text")
        return p.read_text(), str(p)
    return str(system), "<system text>"


def reach_system(
    system: Union[str, PathLike],
    network: Network,
    *,
    grid: Optional[Mapping[str, int]] = None,
    cells: Optional[Tuple[int, int]] = None,
    order: int = 4,
    network_error: str = "auto",
    lifted_weight: int = 1,
    lift_at: float = 0.05,
    max_leaves: int = 256,
    samples: int = 200,
    seed: int = 1,
    timeout: Optional[float] = None,
) -> SystemReachResult:
    """Taylor-model reachable sets of any closed loop written as a system file, as
    ``samara reach --system FILE`` computes them (no files written). ``system``: a path or
    the file's text. ``grid``: ``{state: pieces}`` cuts the initial set into a fixed grid
    whose cells are flown as separate runs (``--grid``), ``cells``: only the cells
    ``[start, end)`` of it (what a shard computes; merge with
    :func:`samara.distributed.merge_reach_system`). The other arguments are the CLI's
    flags (``--order``, ``--network-error``, ``--lifted-weight``, ``--lift-at``,
    ``--max-leaves``, ``--samples``, ``--timeout``)."""
    text, name = _system_source(system)
    return _reach_system_text(
        text, name, network, grid, cells, order=order, network_error=network_error,
        lifted_weight=lifted_weight, lift_at=lift_at, max_leaves=max_leaves, samples=samples,
        seed=seed, timeout=timeout,
    )


def _reach_system_text(
    text: str,
    name: str,
    network: Network,
    grid: Optional[Mapping[str, int]],
    cells: Optional[Tuple[int, int]],
    order: int = 4,
    network_error: str = "auto",
    lifted_weight: int = 1,
    lift_at: float = 0.05,
    max_leaves: int = 256,
    samples: int = 200,
    seed: int = 1,
    timeout: Optional[float] = None,
) -> SystemReachResult:
    out = _samara.reach_system(
        text, name, network._net, {str(k): _count(f"grid[{k!r}]", v, 1, 2**31) for k, v in (grid or {}).items()},
        None if cells is None else (int(cells[0]), int(cells[1])),
        int(order), str(network_error), int(lifted_weight), float(lift_at),
        int(max_leaves), int(samples), int(seed), None if timeout is None else float(timeout),
    )
    return _system_result(out)


def train(
    data: Any,
    method: str = "plain",
    *,
    arch: Sequence[int] = (6, 6, 4, 1),
    epochs: int = 1000,
    batch: int = 50,
    lr: float = 0.06,
    seed: int = 0,
    eps: float = 0.005,
    attack: str = "fgsm",
    lipschitz: float = 0.5,
    weight: Optional[float] = None,
    ystar: float = 2.0,
    normalisation: Optional[Any] = None,
    max_restarts: Optional[int] = None,
    min_r2: Optional[float] = None,
) -> Tuple[Network, Dict[str, Any]]:
    """Train a network as ``samara train`` does (defaults: the published 6-6-4-1 ReLU
    network, Adam lr 0.06, batch 50, 1000 epochs, 10% test split); same seed and data,
    bit-identical network.

    ``data``: rows (inputs, then the output) as an array or a CSV/IDX path, in raw
    units; ``normalisation``: min-max constants (2, columns) (row 1 minimum, row 2
    range; default: from the data). ``method``: plain, adversarial (``attack`` fgsm or
    pgd, radius ``eps``), lipschitz, dl2 or goedel (the built-in P1-P4 with ``ystar``).

    Returns the network (raw units, with its normalisation layers) and the report:
    the fields of ``samara train --json`` plus ``log`` as an array (epoch, loss,
    test RMSE). Raises SamaraError when every attempt gave a degenerate network."""
    if isinstance(data, (str, os.PathLike)):
        data = read_table(data)
    a = np.ascontiguousarray(np.asarray(data, dtype=np.float64))
    if a.ndim != 2:
        raise ValueError(f"data: shape {a.shape}, expected (rows, columns)")
    nm = None
    if normalisation is not None:
        if isinstance(normalisation, (str, os.PathLike)):
            normalisation = read_table(normalisation)
        m = np.asarray(normalisation, dtype=np.float64)
        if m.ndim != 2 or m.shape[0] != 2:
            raise ValueError(f"normalisation: shape {m.shape}, expected (2, columns)")
        nm = (m[0].tolist(), m[1].tolist())
    net, report = _samara.train(
        a.tobytes(), a.shape[0], a.shape[1], nm, method, attack, [int(w) for w in arch],
        int(epochs), int(batch), float(lr), int(seed), float(eps), float(lipschitz),
        None if weight is None else float(weight), float(ystar), max_restarts, min_r2,
    )
    report["log"] = np.array(report["log"], dtype=np.float64).reshape(-1, 3)
    return Network(net, "<trained>"), report

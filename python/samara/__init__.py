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
    "SystemLeaf",
    "Measure",
    "ReachSettings",
    "ReachGoal",
    "ReachCounterexample",
    "ReachLeaf",
    "Reason",
    "NetworkPoint",
    "VerifyCounterexample",
    "RobustnessCell",
    "RobustnessPoint",
    "Flight",
    "TrainReport",
    "Restart",
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


def _same(a: Any, b: Any) -> bool:
    """Equality of result fields: arrays element by element (NaN equal to NaN), lists,
    tuples and dicts item by item, anything else by ``==``."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            return False
        if a.dtype.kind == "f" or b.dtype.kind == "f":
            return bool(np.array_equal(a, b, equal_nan=True))
        return bool(np.array_equal(a, b))
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b)


class _Typed:
    """Base of samara's results: frozen dataclasses built from the library's typed
    values (the native module hands over their fields; no JSON text in between).
    Fields are attributes (listed by ``dir()``), assignment raises
    ``dataclasses.FrozenInstanceError`` (an ``AttributeError``) naming the field,
    ``repr`` is one short line of the scalar fields, numbers that form arrays are numpy
    float64 arrays, ``==`` compares fields (arrays element-wise, NaN equal to NaN) and
    ``as_dict()`` gives every field as plain data (nested results as dicts)."""

    _REPR: Tuple[str, ...] = ()

    def as_dict(self) -> Dict[str, Any]:
        return dataclasses.asdict(self)  # type: ignore[call-overload]

    def __repr__(self) -> str:
        parts = []
        for k in self._REPR:
            v = getattr(self, k)
            if isinstance(v, np.ndarray):
                v = v.tolist()
            r = repr(v)
            parts.append(f"{k}={r if len(r) <= 60 else r[:57] + '...'}")
        more = len(dataclasses.fields(self)) > len(self._REPR)  # type: ignore[arg-type]
        return f"{type(self).__name__}({', '.join(parts)}{', ...' if more else ''})"

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(
            _same(getattr(self, f.name), getattr(other, f.name))
            for f in dataclasses.fields(self)  # type: ignore[arg-type]
        )

    __hash__ = None  # type: ignore[assignment]

    def __setattr__(self, k: str, v: Any) -> None:
        raise dataclasses.FrozenInstanceError(
            f"{type(self).__name__}.{k}: a result is read-only; "
            f"dataclasses.replace(r, {k}=...) makes a changed copy"
        )

    def __delattr__(self, k: str) -> None:
        raise dataclasses.FrozenInstanceError(f"{type(self).__name__}.{k}: a result is read-only")


_T = Any


def _result(cls: _T) -> _T:
    """A frozen dataclass over :class:`_Typed` (its messages for assignment)."""
    cls = dataclasses.dataclass(frozen=True, repr=False, eq=False)(cls)
    # The dataclass's own __setattr__/__delattr__ say only "cannot assign to field";
    # _Typed's name the field and the way to a changed copy.
    del cls.__setattr__
    del cls.__delattr__
    return cls


def _floats(v: Any, shape: Tuple[int, ...] = ()) -> np.ndarray:
    """A float64 array of `v` (None: NaN), of `shape` when `v` is empty."""
    if v is None:
        return np.full(shape or (2,), np.nan)
    a = np.array(v, dtype=np.float64)
    return a.reshape(shape) if a.size == 0 and shape else a


def _opt_pair(v: Any) -> Optional[Tuple[float, float]]:
    return None if v is None else (float(v[0]), float(v[1]))


@_result
class Reason(_Typed):
    """Why a search gave no verdict: ``kind`` (``timeout``, ``node_limit``, ...) and the
    human ``message``."""

    kind: str
    message: str

    _REPR = ("kind",)

    @classmethod
    def _of(cls, d: Optional[Dict[str, Any]]) -> Optional["Reason"]:
        return None if d is None else cls(**d)


@_result
class NetworkPoint(_Typed):
    """A point of one network application: the ``network``'s name and ``values`` (its
    inputs and outputs by name, in the spec's physical units)."""

    network: str
    values: Dict[str, float]

    _REPR = ("network",)


def _point(v: Optional[List[Dict[str, Any]]]) -> Optional[List[NetworkPoint]]:
    return None if v is None else [NetworkPoint(network=a["network"], values=dict(a["values"])) for a in v]


def _flat_point(apps: List[NetworkPoint]) -> Dict[str, float]:
    out: Dict[str, float] = {}
    multi = len(apps) > 1
    for i, a in enumerate(apps):
        for k, v in a.values.items():
            out[f"{a.network}[{i}].{k}" if multi else k] = v
    return out


@_result
class VerifyCounterexample(_Typed):
    """The counterexample of a verdict row: ``point`` (one :class:`NetworkPoint` per
    network application), its ``margin`` and ``exact_check`` (re-evaluated exactly);
    or, for an unknown verdict with a candidate, only ``reason``."""

    point: Optional[List[NetworkPoint]]
    margin: Optional[float]
    exact_check: Optional[bool]
    reason: Optional[str]

    _REPR = ("margin", "exact_check", "reason")

    @classmethod
    def _of(cls, d: Optional[Dict[str, Any]]) -> Optional["VerifyCounterexample"]:
        if d is None:
            return None
        return cls(point=_point(d.get("point")), margin=d.get("margin"),
                   exact_check=d.get("exact_check"), reason=d.get("reason"))


@_result
class VerifyResult(_Typed):
    """One property instance of :meth:`Spec.verify` (the library's verdict row, the
    fields of ``samara verify --json``): ``property``, ``verdict`` ('proved' |
    'violated' | 'unknown'), ``counterexample`` (:class:`VerifyCounterexample` or
    None), ``seconds``, ``vacuous``, ``vacuity``, ``unknown_reason``
    (:class:`Reason` or None). ``witness`` is the counterexample's values as one dict."""

    property: str
    verdict: str
    counterexample: Optional[VerifyCounterexample]
    seconds: float
    vacuous: bool
    vacuity: Optional[str]
    unknown_reason: Optional[Reason]

    _REPR = ("property", "verdict", "seconds")

    @classmethod
    def _of(cls, d: Dict[str, Any]) -> "VerifyResult":
        return cls(**dict(d, counterexample=VerifyCounterexample._of(d["counterexample"]),
                          unknown_reason=Reason._of(d["unknown_reason"])))

    @property
    def witness(self) -> Optional[Dict[str, float]]:
        cx = self.counterexample
        if cx is None or cx.point is None:
            return None
        return _flat_point(cx.point)


@_result
class CriticalResult(_Typed):
    """The result of :meth:`Spec.critical` (the library's critical value, the fields of
    ``samara critical --json``): ``property``, ``parameter``, ``holds`` ('above' |
    'below' | 'everywhere' | 'nowhere' | 'unknown'), ``critical``, ``bound``,
    ``threshold``, ``attained``, ``vacuous``, ``domain_extreme``,
    ``counterexample_range`` (inf, sup), ``witness`` (one :class:`NetworkPoint` per
    application, or None), ``complete``, ``unknown_reason`` (:class:`Reason` or None),
    ``seconds``. ``witness_values`` is the witness as one dict."""

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
    witness: Optional[List[NetworkPoint]]
    complete: bool
    unknown_reason: Optional[Reason]
    seconds: float

    _REPR = ("property", "parameter", "holds", "critical", "threshold")

    @classmethod
    def _of(cls, d: Dict[str, Any]) -> "CriticalResult":
        return cls(**dict(d, counterexample_range=tuple(d["counterexample_range"]),
                          witness=_point(d["witness"]), unknown_reason=Reason._of(d["unknown_reason"])))

    @property
    def witness_values(self) -> Optional[Dict[str, float]]:
        return None if self.witness is None else _flat_point(self.witness)


@_result
class RobustnessCell(_Typed):
    """One cell of the robustness table: the points at radius ``eps`` and bound ``L``
    that are ``proved``, ``violated`` or ``unknown``, and ``success_rate`` (proved over
    all points)."""

    eps: float
    L: float
    proved: int
    violated: int
    unknown: int
    success_rate: float

    _REPR = ("eps", "L", "proved", "violated", "unknown")


@_result
class RobustnessPoint(_Typed):
    """One data point at one radius (a row of ``samara robustness --out``'s CSV):
    ``index`` (the row of ``data``, counted from 0), ``eps``, the output's bounds
    ``f_min``/``f_max`` over the ball, ``reference``, ``max_deviation`` and the
    Lipschitz bounds ``lipschitz_lower``/``lipschitz_upper``."""

    index: int
    eps: float
    f_min: float
    f_max: float
    reference: float
    max_deviation: float
    lipschitz_lower: float
    lipschitz_upper: float

    _REPR = ("index", "eps", "max_deviation")


@_result
class RobustnessResult(_Typed):
    """The result of :func:`robustness` (the library's robustness table, the fields of
    ``samara robustness --json``): ``form``, ``points``, ``seconds``, ``table`` (rows
    eps, columns L, each a :class:`RobustnessCell`), plus ``per_point`` (one
    :class:`RobustnessPoint` per point and radius). ``success_rate`` is the table as a
    numpy array."""

    form: str
    points: int
    seconds: float
    table: List[List[RobustnessCell]]
    per_point: List[RobustnessPoint]

    _REPR = ("form", "points", "seconds")

    @classmethod
    def _of(cls, d: Dict[str, Any]) -> "RobustnessResult":
        return cls(form=d["form"], points=d["points"], seconds=d["seconds"],
                   table=[[RobustnessCell(**c) for c in row] for row in d["table"]],
                   per_point=[RobustnessPoint(**p) for p in d["per_point"]])

    @property
    def success_rate(self) -> np.ndarray:
        return np.array([[c.success_rate for c in row] for row in self.table], dtype=np.float64)


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
    ) -> List[VerifyResult]:
        """Verify every property (or only ``property``): one :class:`VerifyResult` per
        instance (a data-set property has one per point), as ``samara verify --json``.

        ``datasets`` maps a data-set name to a CSV/IDX path or a numpy array (inputs,
        then the label). ``timeout`` is per query in seconds (``math.inf``: none)."""
        with _Datasets(datasets) as ds:
            rows, ws = self._spec.verify(
                _nets(networks), _params(params), ds, property, _timeout(timeout), _count("max_nodes", max_nodes)
            )
        _warn(ws)
        return [VerifyResult._of(d) for d in rows]

    def critical(
        self,
        property: str,
        param: str,
        networks: Mapping[str, Network],
        params: Optional[Mapping[str, float]] = None,
        datasets: Optional[Mapping[str, Any]] = None,
        timeout: float = 60.0,
        max_nodes: int = 200_000,
    ) -> CriticalResult:
        """The critical value of parameter ``param`` (declared with a range) for
        ``property``, as ``samara critical --json``."""
        with _Datasets(datasets) as ds:
            d, ws = self._spec.critical(
                _str("property", property), _str("param", param), _nets(networks), _params(params), ds,
                _timeout(timeout), _count("max_nodes", max_nodes)
            )
        _warn(ws)
        return CriticalResult._of(d)

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
        _network("network", network),
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
    return RobustnessResult._of(d)


STATE_NAMES = ["v_xp", "v_yp", "omega", "theta", "x", "y", "E"]


def simulate(
    model: str = "plate6",
    controller: Union[str, float, Network] = "pid",
    y0: Optional[Sequence[float]] = None,
    integrator: str = "ode45",
    horizon: float = 20.0,
    period: float = 0.5,
    clip: bool = True,
) -> List["Flight"]:
    """Closed-loop flights as ``samara simulate`` flies them (no files written).

    ``controller``: ``"pid"``, a number (a constant ex in [0.181, 0.193]) or a
    :class:`Network` (6 raw inputs, 1 raw output; clipped to [0.181, 0.193] unless
    ``clip=False``). ``y0``: initial heights (default: the nine published starts).

    One :class:`Flight` per start."""
    net = None
    ex = 0.0
    if isinstance(controller, Network):
        kind, net = "network", controller._net
    elif isinstance(controller, str) and controller.startswith("constant:"):
        kind, ex = "constant", float(controller.split(":", 1)[1])
    elif isinstance(controller, (int, float)) and not isinstance(controller, bool):
        kind, ex = "constant", float(controller)
    elif isinstance(controller, (str, os.PathLike)) and str(controller).endswith((".onnx", ".nnet")):
        raise TypeError(
            f"controller={str(controller)!r}: a path; pass samara.Network.from_onnx(path) (or 'pid', or a number)"
        )
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
            Flight(
                y0=initial[5],
                t=a[:, 0].copy(),
                ex=a[:, 1].copy(),
                states=a[:, 2:].copy(),
                state_names=STATE_NAMES[:dim],
                initial=np.array(initial),
                final_state=dict(zip(STATE_NAMES[:dim], a[-1, 2:].tolist())),
                rhs_evals=evals,
            )
        )
    return out


@_result
class Flight(_Typed):
    """One closed-loop flight of :func:`simulate`: its start height ``y0``, ``t`` (n,),
    ``ex`` (n,) (the control held from each row on), ``states`` (n, dim) with columns
    ``state_names``, ``initial`` (the initial state), ``final_state`` (by name) and
    ``rhs_evals`` (right-hand-side evaluations)."""

    y0: float
    t: np.ndarray
    ex: np.ndarray
    states: np.ndarray
    state_names: List[str]
    initial: np.ndarray
    final_state: Dict[str, float]
    rhs_evals: int

    _REPR = ("y0", "rhs_evals")


def _interval(name: str, v: Any) -> Tuple[float, float]:
    """An interval given as (lo, hi) or one value; anything longer is refused (a
    three-value tuple is not an interval)."""
    a = np.atleast_1d(np.asarray(v, dtype=np.float64))
    if a.ndim != 1 or len(a) not in (1, 2):
        raise ValueError(f"{name}={v!r}: give an interval as (lo, hi) or a single value, not {a.size} values")
    return (float(a[0]), float(a[-1]))


def _network(name: str, v: Any) -> "_samara.Network":
    """The native network of argument `name`, or a TypeError naming it (a path is not
    a network)."""
    if not isinstance(v, Network):
        hint = " (a path: load it with samara.Network.from_onnx(path))" if isinstance(v, (str, os.PathLike)) else ""
        raise TypeError(f"{name}={v!r}: expected samara.Network{hint}")
    return v._net


@_result
class ReachGoal(_Typed):
    """The goal |x + y| <= ``ystar`` at the horizon, or on [``from_``, horizon]."""

    ystar: float
    from_: Optional[float]

    _REPR = ("ystar", "from_")


@_result
class ReachSettings(_Typed):
    """The settings of a :func:`reach` run as ``reach.json`` records them: ``network``
    (where the network came from: its path, ``<bytes>``, ``<torch ...>``), ``model``,
    ``init`` (state -> (lo, hi)), ``horizon``, ``period``, ``clip``, ``reset_filter``,
    ``goal`` (:class:`ReachGoal` or None), ``max_leaves``, ``initial_splits``,
    ``samples``, ``seed`` and ``threads`` (the worker threads it ran on)."""

    network: str
    model: str
    init: Dict[str, Tuple[float, float]]
    horizon: float
    period: float
    clip: Optional[Tuple[float, float]]
    reset_filter: bool
    goal: Optional[ReachGoal]
    max_leaves: int
    initial_splits: int
    samples: int
    seed: int
    threads: int

    _REPR = ("network", "model", "horizon", "period", "threads")

    @classmethod
    def _of(cls, d: Dict[str, Any]) -> "ReachSettings":
        g = d["goal"]
        return cls(**dict(
            d,
            init={k: (float(v[0]), float(v[1])) for k, v in d["init"].items()},
            clip=_opt_pair(d["clip"]),
            goal=None if g is None else ReachGoal(ystar=g["ystar"], from_=g["from"]),
        ))


@_result
class ReachCounterexample(_Typed):
    """A simulated flight that misses the goal: its ``initial`` state, the time ``t``
    of the miss and its ``x_plus_y`` there."""

    initial: np.ndarray
    t: float
    x_plus_y: float

    _REPR = ("t", "x_plus_y")


def _steps(steps: List[Dict[str, Any]], nb: int) -> Dict[str, np.ndarray]:
    """The per-instant records of a sub-box as arrays (an absent control: NaN)."""
    k = len(steps)
    return dict(
        t=np.array([s["t"] for s in steps], dtype=np.float64),
        bbox=_floats([s["bbox"] for s in steps], (k, nb, 2)),
        x_plus_y=_floats([s["x_plus_y"] for s in steps], (k, 2)),
        x_plus_y_period=_floats([s["x_plus_y_period"] for s in steps], (k, 2)),
        ex=_floats([[math.nan, math.nan] if s["ex"] is None else s["ex"] for s in steps], (k, 2)),
    )


@_result
class ReachLeaf(_Typed):
    """A sub-box of the initial set and its enclosures: ``init`` (states, 2), the
    indices ``params`` of its parameter states, per control instant reached ``t`` (k,),
    ``bbox`` (k, 6, 2) of the six physical states, ``x_plus_y`` and
    ``x_plus_y_period`` (k, 2), ``ex`` (k, 2) (NaN at the horizon); ``failure`` (why it
    stopped early, or None), ``flow_steps`` (accepted, rejected) and ``max_dev``."""

    init: np.ndarray
    params: List[int]
    t: np.ndarray
    bbox: np.ndarray
    x_plus_y: np.ndarray
    x_plus_y_period: np.ndarray
    ex: np.ndarray
    failure: Optional[str]
    flow_steps: Tuple[int, int]
    max_dev: float

    _REPR = ("failure", "flow_steps")


def _verdict(v: Dict[str, Any]) -> Tuple[str, Optional[str]]:
    return v["verdict"], v.get("reason")


@_result
class ReachResult(_Typed):
    """The result of :func:`reach` (the library's ``reach.json`` of ``samara reach``):
    ``settings`` (:class:`ReachSettings`), ``verdict`` ('proved' | 'violated' |
    'unknown' | 'none' without a goal), ``reason`` (why not proved, or None),
    ``counterexample`` (:class:`ReachCounterexample` of a violation, or None),
    ``final_x_plus_y`` and ``sampled_x_plus_y`` (2,) (the enclosure and the sampled
    range of x + y at the horizon), ``width_ratio``, ``subproblems``, ``seconds``,
    ``sampled_trajectories``, ``enclosure_lost`` (where the sets stopped before the
    horizon, which ``samara reach`` reports with exit code 1, or None), ``warnings``
    (a network in the wrong units), ``state_names``, ``leaves`` (one
    :class:`ReachLeaf` per sub-box), and the hull over the sub-boxes per control
    instant:

    - ``t``: (k,) the control instants;
    - ``bbox``: (k, 6, 2) of the six physical states;
    - ``x_plus_y``: (k, 2) the enclosure of x + y at each instant; ``x_plus_y_period``:
      over the period ending there;
    - ``ex``: (k, 2) the control held from each instant (NaN at the horizon).

    Where a sub-box stopped early (``leaf.failure``) the later instants are unbounded
    (-inf, inf)."""

    settings: ReachSettings
    verdict: str
    reason: Optional[str]
    counterexample: Optional[ReachCounterexample]
    final_x_plus_y: np.ndarray
    sampled_x_plus_y: np.ndarray
    width_ratio: float
    subproblems: int
    seconds: float
    sampled_trajectories: int
    enclosure_lost: Optional[str]
    warnings: List[str]
    state_names: List[str]
    leaves: List[ReachLeaf]
    t: np.ndarray
    bbox: np.ndarray
    x_plus_y: np.ndarray
    x_plus_y_period: np.ndarray
    ex: np.ndarray

    _REPR = ("verdict", "final_x_plus_y", "subproblems", "seconds")

    @property
    def proved(self) -> bool:
        return self.verdict == "proved"

    @classmethod
    def _of(cls, d: Dict[str, Any]) -> "ReachResult":
        settings = ReachSettings._of(d["settings"])
        nb = 6
        leaves = [
            ReachLeaf(init=_floats(l["init"], (0, 2)), params=list(l["params"]), **_steps(l["steps"], nb),
                      failure=l["failure"], flow_steps=tuple(l["flow_steps"]), max_dev=l["max_dev"])
            for l in d["leaves"]
        ]
        # The hull over the sub-boxes at each control instant (unbounded after a
        # sub-box stopped).
        k = int(round(settings.horizon / settings.period)) + 1
        t = np.array([i * settings.period for i in range(k)])
        bbox = np.empty((k, nb, 2))
        bbox[..., 0], bbox[..., 1] = np.inf, -np.inf
        xy = np.tile([np.inf, -np.inf], (k, 1))
        xyp = np.tile([np.inf, -np.inf], (k, 1))
        ex = np.tile([np.inf, -np.inf], (k, 1))
        for leaf in leaves:
            n = len(leaf.t)
            t[:n] = leaf.t
            for arr, mine in ((bbox, leaf.bbox[:, :nb]), (xy, leaf.x_plus_y), (xyp, leaf.x_plus_y_period)):
                lo = np.nan_to_num(mine[..., 0], nan=-np.inf)
                hi = np.nan_to_num(mine[..., 1], nan=np.inf)
                arr[:n, ..., 0] = np.minimum(arr[:n, ..., 0], lo)
                arr[:n, ..., 1] = np.maximum(arr[:n, ..., 1], hi)
                arr[n:, ..., 0], arr[n:, ..., 1] = -np.inf, np.inf
            ex[:n, 0] = np.fmin(ex[:n, 0], leaf.ex[:, 0])
            ex[:n, 1] = np.fmax(ex[:n, 1], leaf.ex[:, 1])
        ex[np.isinf(ex[:, 0]) & (ex[:, 0] > 0)] = np.nan
        verdict, reason = _verdict(d["verdict"])
        cx = d["verdict"].get("counterexample")
        return cls(
            settings=settings,
            verdict=verdict,
            reason=reason,
            counterexample=None if cx is None else ReachCounterexample(
                initial=np.array(cx["initial"], dtype=np.float64), t=cx["t"], x_plus_y=cx["x_plus_y"]),
            final_x_plus_y=_floats(d["final_x_plus_y"]),
            sampled_x_plus_y=_floats(d["sampled_x_plus_y"]),
            width_ratio=d["width_ratio"],
            subproblems=d["subproblems"],
            seconds=d["seconds"],
            sampled_trajectories=d["sampled_trajectories"],
            enclosure_lost=d["enclosure_lost"],
            warnings=list(d["warnings"]),
            state_names=list(d["state_names"]),
            leaves=leaves,
            t=t, bbox=bbox, x_plus_y=xy, x_plus_y_period=xyp, ex=ex,
        )


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
    net = _network("network", network)
    iv: Dict[str, Tuple[float, float]] = {"y": _interval("y0", y0)}
    for k, v in (init or {}).items():
        if k == "y":
            raise ValueError("init['y']: give the height interval as y0")
        iv[k] = _interval(f"init[{k!r}]", v)
    d = _samara.reach(
        net, model, iv, float(horizon), float(period),
        None if goal_ystar is None else float(goal_ystar),
        None if goal_from is None else float(goal_from),
        bool(clip),
        None if max_leaves is None else _count("max_leaves", max_leaves),
        None if samples is None else _count("samples", samples),
        None if seed is None else _count("seed", seed, 0, 2**64 - 1),
        network._source,
        None if threads is None else _count("threads", threads, 1, 1024),
    )
    r = ReachResult._of(d)
    # What `samara reach` prints on stderr: a network in the wrong units, an enclosure
    # lost before the horizon (then ``r.enclosure_lost`` says where).
    for w in r.warnings:
        warnings.warn(w, stacklevel=2)
    if r.enclosure_lost:
        warnings.warn(r.enclosure_lost, stacklevel=2)
    return r


@_result
class Measure(_Typed):
    """A measure of a system file's settings at the horizon: its ``name``, the sets'
    ``enclosure`` and the flights' ``sampled`` range (each (lo, hi) or None), and their
    width ``ratio``."""

    name: str
    enclosure: Optional[Tuple[float, float]]
    sampled: Optional[Tuple[float, float]]
    ratio: Optional[float]

    _REPR = ("name", "enclosure", "ratio")


@_result
class SystemLeaf(_Typed):
    """A sub-box of a system's initial set: ``init`` (states, 2), its hulls per control
    instant ``instants`` and per period ``periods`` (k, states, 2), ``failure`` (why it
    stopped early, or None), ``stopped_at`` (the time it stopped, or None) and
    ``end_measures`` (measures, 2)."""

    init: np.ndarray
    instants: np.ndarray
    periods: np.ndarray
    failure: Optional[str]
    stopped_at: Optional[float]
    end_measures: np.ndarray

    _REPR = ("failure", "stopped_at")


def _boxes(v: List[Any], n: int) -> np.ndarray:
    """(k, n, 2) intervals per instant."""
    return _floats(v, (len(v), n, 2)) if len(v) == 0 else _floats(v)


def _network_error_text(v: Any) -> str:
    """`interval`, `symbolic:N` (as the argument ``network_error`` takes it)."""
    if isinstance(v, str):
        return v
    (kind, fields), = v.items()
    return f"{kind}:{fields['extra']}"


def _network_error_native(t: str) -> Any:
    kind, _, n = t.partition(":")
    return kind if not n else {kind: {"extra": int(n)}}


@_result
class SystemReachResult(_Typed):
    """The result of :func:`reach_system` (the library's ``result`` of
    ``samara reach --system``'s ``reach.json``): ``system``, ``verdict`` ('proved' |
    'violated' | 'unknown' | 'none'), ``reason`` (the goal a violation misses, or why
    the verdict is unknown; None otherwise), ``counterexample`` (the initial state of a
    violating flight, or None), ``instants`` and ``periods`` ((k, states, 2): the hull
    over the sub-boxes per control instant / period), ``boxes``, ``covered``,
    ``order``, ``network_error`` (``interval`` or ``symbolic:N``), ``seconds``,
    ``leaves`` (:class:`SystemLeaf`), ``measures`` (:class:`Measure`), ``cells``
    ((start, end) of a grid run, else None) and ``total_cells``. ``bbox`` is
    ``instants``."""

    system: str
    verdict: str
    reason: Optional[str]
    counterexample: Optional[np.ndarray]
    instants: np.ndarray
    periods: np.ndarray
    boxes: int
    covered: float
    order: int
    network_error: str
    seconds: float
    leaves: List[SystemLeaf]
    measures: List[Measure]
    cells: Optional[Tuple[int, int]]
    total_cells: Optional[int]

    _REPR = ("system", "verdict", "boxes", "covered", "cells", "seconds")

    @property
    def bbox(self) -> np.ndarray:
        return self.instants

    @classmethod
    def _of(cls, part: Dict[str, Any]) -> "SystemReachResult":
        d = part["reach"]
        v = d["verdict"]
        n = len(v["initial"]) if "initial" in v else None
        leaves = [
            SystemLeaf(init=_floats(l["init"], (0, 2)), instants=_boxes(l["instants"], len(l["init"])),
                       periods=_boxes(l["periods"], len(l["init"])), failure=l["failure"],
                       stopped_at=l["stopped_at"], end_measures=_floats(l["end_measures"], (0, 2)))
            for l in d["leaves"]
        ]
        dim = len(leaves[0].init) if leaves else (n or 0)
        return cls(
            system=d["system"],
            verdict=v["verdict"],
            reason=v.get("reason", v.get("goal")),
            counterexample=None if "initial" not in v else np.array(v["initial"], dtype=np.float64),
            instants=_boxes(d["instants"], dim),
            periods=_boxes(d["periods"], dim),
            boxes=d["boxes"],
            covered=d["covered"],
            order=d["order"],
            network_error=_network_error_text(d["network_error"]),
            seconds=d["seconds"],
            leaves=leaves,
            measures=[Measure(name=m["name"], enclosure=_opt_pair(m["enclosure"]),
                              sampled=_opt_pair(m["sampled"]), ratio=m["ratio"]) for m in d["measures"]],
            cells=None if part["cells"] is None else tuple(part["cells"]),
            total_cells=part["total_cells"],
        )

    def _native(self) -> Dict[str, Any]:
        """The fields the native merge reads back (the inverse of ``_of``)."""
        v: Dict[str, Any] = {"verdict": self.verdict}
        if self.verdict == "violated":
            v["initial"] = self.counterexample
            v["goal"] = self.reason
        elif self.verdict == "unknown":
            v["reason"] = self.reason
        reach = dict(
            system=self.system, verdict=v, instants=self.instants, periods=self.periods,
            boxes=self.boxes, covered=self.covered, order=self.order,
            network_error=_network_error_native(self.network_error), seconds=self.seconds,
            leaves=[dict(init=l.init, instants=l.instants, periods=l.periods, failure=l.failure,
                         stopped_at=l.stopped_at, end_measures=l.end_measures) for l in self.leaves],
            measures=[dict(name=m.name, enclosure=m.enclosure, sampled=m.sampled, ratio=m.ratio)
                      for m in self.measures],
        )
        return {"cells": self.cells, "total_cells": self.total_cells, "reach": reach}


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
    time_order: Optional[int] = None,
    step_tol: Optional[float] = None,
) -> SystemReachResult:
    """Taylor-model reachable sets of any closed loop written as a system file, as
    ``samara reach --system FILE`` computes them (no files written). ``system``: a path or
    the file's text. ``grid``: ``{state: pieces}`` cuts the initial set into a fixed grid
    whose cells are flown as separate runs (``--grid``), ``cells``: only the cells
    ``[start, end)`` of it (what a shard computes; merge with
    :func:`samara.distributed.merge_reach_system`). The other arguments are the CLI's
    flags (``--order``, ``--network-error``, ``--lifted-weight``, ``--lift-at``,
    ``--max-leaves``, ``--samples``, ``--timeout``, ``--time-order``, ``--step-tol``;
    ``None``: the flow's defaults, order 6 in time and a step tolerance of 1e-7)."""
    text, name = _system_source(system)
    return _reach_system_text(
        text, name, network, grid, cells, order=order, network_error=network_error,
        lifted_weight=lifted_weight, lift_at=lift_at, max_leaves=max_leaves, samples=samples,
        seed=seed, timeout=timeout, time_order=time_order, step_tol=step_tol,
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
    time_order: Optional[int] = None,
    step_tol: Optional[float] = None,
) -> SystemReachResult:
    net = _network("network", network)
    if cells is not None:
        if len(cells) != 2:
            raise ValueError(f"cells={cells!r}: give (start, end)")
        cells = (_count("cells[0]", cells[0]), _count("cells[1]", cells[1]))
    out = _samara.reach_system(
        text, name, net, {str(k): _count(f"grid[{k!r}]", v, 1, 2**31) for k, v in (grid or {}).items()},
        cells, _count("order", order, 0, 2**32 - 1), _str("network_error", network_error),
        _count("lifted_weight", lifted_weight, 0, 2**32 - 1), float(lift_at),
        _count("max_leaves", max_leaves), _count("samples", samples), _count("seed", seed, 0, 2**64 - 1),
        None if timeout is None else float(timeout),
        None if time_order is None else _count("time_order", time_order, -(2**63), 2**63 - 1),
        None if step_tol is None else float(step_tol),
    )
    return SystemReachResult._of(out)


@_result
class Restart(_Typed):
    """A restart of training from a degenerate network: the ``attempt`` (from 0), the
    ``seed`` of the degenerate network, the ``epoch`` it was found at and the
    ``reason``."""

    attempt: int
    seed: int
    epoch: int
    reason: str

    _REPR = ("attempt", "epoch", "reason")


@_result
class TrainReport(_Typed):
    """The report of :func:`train` (the fields of ``samara train --json`` but the file
    paths): ``method``, ``test_rows``, the held-out ``r2``, the training ``r2_train``,
    ``rmse``, ``mae``, ``eps``, ``attack_worst_deviation``, ``attack_mean_deviation``,
    ``seed``, ``init_seed`` (the seed of the kept network), ``restarts`` and
    ``restart_log`` (:class:`Restart`), and ``log`` (epochs, 3): epoch, loss, test
    RMSE."""

    method: str
    test_rows: int
    r2: float
    r2_train: float
    rmse: float
    mae: float
    eps: float
    attack_worst_deviation: float
    attack_mean_deviation: float
    seed: int
    init_seed: int
    restarts: int
    restart_log: List[Restart]
    log: np.ndarray

    _REPR = ("method", "r2", "rmse", "restarts")

    @classmethod
    def _of(cls, d: Dict[str, Any]) -> "TrainReport":
        return cls(**dict(d, restart_log=[Restart(**r) for r in d["restart_log"]],
                          log=_floats(d["log"], (0, 3)).reshape(-1, 3)))


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
) -> Tuple[Network, TrainReport]:
    """Train a network as ``samara train`` does (defaults: the published 6-6-4-1 ReLU
    network, Adam lr 0.06, batch 50, 1000 epochs, 10% test split); same seed and data,
    bit-identical network.

    ``data``: rows (inputs, then the output) as an array or a CSV/IDX path, in raw
    units; ``normalisation``: min-max constants (2, columns) (row 1 minimum, row 2
    range; default: from the data). ``method``: plain, adversarial (``attack`` fgsm or
    pgd, radius ``eps``), lipschitz, dl2 or goedel (the built-in P1-P4 with ``ystar``).

    Returns the network (raw units, with its normalisation layers) and its
    :class:`TrainReport`. Raises SamaraError when every attempt gave a degenerate
    network."""
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
        a.tobytes(), a.shape[0], a.shape[1], nm, _str("method", method), _str("attack", attack),
        [_count(f"arch[{i}]", w) for i, w in enumerate(arch)],
        _count("epochs", epochs), _count("batch", batch), float(lr), _count("seed", seed, 0, 2**64 - 1),
        float(eps), float(lipschitz), None if weight is None else float(weight), float(ystar),
        None if max_restarts is None else _count("max_restarts", max_restarts),
        None if min_r2 is None else float(min_r2),
    )
    return Network(net, "<trained>"), TrainReport._of(report)
